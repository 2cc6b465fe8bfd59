"""NSSDA/ASPRS accuracy statements (geoblock.adjust.accuracy).

Golden factors: FGDC-STD-007.3-1998 (NSSDA), Appendix 3-A: CE95 = 2.4477 sigma (circular),
LE95 = 1.9600 sigma; CE90 = 2.1460 sigma and LE90 = 1.6449 sigma are the 90 % counterparts.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock.adjust import accuracy as acc


def test_factors_match_the_standard():
    assert acc.CE90_FACTOR == pytest.approx(2.1460, abs=5e-5)
    assert acc.CE95_FACTOR == pytest.approx(2.4477, abs=5e-5)
    assert acc.LE90_FACTOR == pytest.approx(1.6449, abs=5e-5)
    assert acc.LE95_FACTOR == pytest.approx(1.9600, abs=5e-5)
    assert acc.nssda_ce(1.0, 1.0, 0.95) == pytest.approx(2.4477, abs=5e-5)
    assert acc.nssda_le(1.0, 0.90) == pytest.approx(1.6449, abs=5e-5)


def test_predicted_ce_of_a_circular_error_is_the_factor():
    cov = np.diag([4.0, 4.0])
    assert acc.predicted_ce(cov, 0.90) == pytest.approx(2.0 * acc.CE90_FACTOR, rel=1e-8)
    assert acc.predicted_ce(cov, 0.95) == pytest.approx(2.0 * acc.CE95_FACTOR, rel=1e-8)


def test_predicted_ce_of_a_line_error_is_the_normal_quantile():
    cov = np.diag([9.0, 0.0])
    assert acc.predicted_ce(cov, 0.90) == pytest.approx(3.0 * acc.LE90_FACTOR, rel=1e-8)


@settings(max_examples=25, deadline=None)
@given(st.floats(0.1, 10.0), st.floats(0.1, 10.0), st.floats(0.0, math.pi))
def test_predicted_ce_agrees_with_monte_carlo(sa, sb, angle):
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    cov = rot @ np.diag([sa**2, sb**2]) @ rot.T
    ce = acc.predicted_ce(cov, 0.90)
    e = np.random.default_rng(1).multivariate_normal([0, 0], cov, 200_000)
    assert acc.empirical_ce(e[:, 0], e[:, 1], 0.90) == pytest.approx(ce, rel=0.01)


def test_predicted_ce_of_a_population_is_the_mixture_quantile():
    covs = np.array([np.eye(2) * 1.0, np.eye(2) * 25.0])
    rng = np.random.default_rng(2)
    e = np.concatenate([rng.normal(0, 1, (100_000, 2)), rng.normal(0, 5, (100_000, 2))])
    ce = acc.predicted_ce(covs, 0.90)
    assert acc.empirical_ce(e[:, 0], e[:, 1], 0.90) == pytest.approx(ce, rel=0.01)
    # neither the mean sigma's nor the RMS sigma's circular error
    assert not math.isclose(ce, acc.CE90_FACTOR * 3.0, rel_tol=0.05)


def test_predicted_le_and_empirical_le():
    s = np.array([1.0, 3.0])
    rng = np.random.default_rng(3)
    z = np.concatenate([rng.normal(0, 1, 100_000), rng.normal(0, 3, 100_000)])
    assert acc.empirical_le(z, 0.90) == pytest.approx(acc.predicted_le(s, 0.90), rel=0.01)
    assert acc.predicted_le([2.0], 0.90) == pytest.approx(2.0 * acc.LE90_FACTOR, rel=1e-8)


def test_nan_and_bad_probability():
    assert math.isnan(acc.predicted_ce(np.full((2, 2), np.nan)))
    assert math.isnan(acc.empirical_ce([np.nan], [1.0]))
    with pytest.raises(ValueError, match="probability"):
        acc.predicted_ce(np.eye(2), 90)
