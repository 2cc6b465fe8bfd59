import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock import ParameterSet
from geoblock.errors import SerializationError


def make():
    return ParameterSet(("a0", "b0"), [1.0, 2.0], ("px", "px"), [0.5, np.inf])


def test_immutable_and_with_values():
    p = make()
    with pytest.raises(ValueError):
        p.values[0] = 3.0
    q = p.with_values({"b0": 5.0})
    assert p["b0"] == 2.0 and q["b0"] == 5.0
    assert q.sigmas[0] == 0.5 and np.isinf(q.sigmas[1])
    with pytest.raises(ValueError, match=r"expected 2 values \['a0', 'b0'\]"):
        p.with_values([1.0])
    with pytest.raises(KeyError, match="no parameter 'c0'"):
        p.with_values({"c0": 1.0})


def test_json_round_trip_with_free_parameters():
    p = make().with_adjustable(["a0"])
    text = json.dumps(p.to_dict(), allow_nan=False)
    q = ParameterSet.from_dict(json.loads(text))
    assert q == p and list(q.adjustable) == [True, False]
    assert np.allclose(q.prior_covariance, np.diag([0.25, np.inf]))


def test_covariance():
    cov = [[0.25, 0.1], [0.1, 1.0]]
    p = ParameterSet(("a", "b"), [0, 0], covariance=cov)
    assert np.allclose(p.sigmas, [0.5, 1.0])
    with pytest.raises(ValueError, match="symmetric"):
        ParameterSet(("a", "b"), [0, 0], covariance=[[1, 0.1], [0, 1]])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"names": ("a", "a"), "values": [0, 0]}, "duplicate"),
        ({"names": ("a",), "values": [0, 0]}, "values of shape"),
        ({"names": ("a",), "values": [0], "sigmas": [0.0]}, "sigmas must be > 0"),
    ],
)
def test_invalid(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ParameterSet(**kwargs)


def test_from_dict_errors():
    with pytest.raises(SerializationError, match="invalid parameter set"):
        ParameterSet.from_dict({"names": ["a"]})


def test_location_accuracy_helper():
    from geoblock.errors import ModelFormatError, ParameterSetError
    from geoblock.models.parameters import accuracy_or_stored, location_accuracy

    assert location_accuracy("2.5", "x") == 2.5 and location_accuracy(3, "x") == 3.0
    for bad in (0.0, -1.0, float("nan"), float("inf"), "ten", None, [1.0]):
        with pytest.raises(ModelFormatError, match=r"^where: must be finite and > 0"):
            location_accuracy(bad, "where")
    with pytest.raises(ParameterSetError):
        location_accuracy(0.0, "where", ParameterSetError)
    assert accuracy_or_stored(5.0, 12.0, "M", "dg") == 5.0
    assert accuracy_or_stored(None, 12.0, "M", "dg") == 12.0
    with pytest.raises(ParameterSetError, match=r"M: parameter set 'dg'.*pass sigmas="):
        accuracy_or_stored(None, None, "M", "dg", advice="sigmas=")
    with pytest.raises(ParameterSetError, match=r"M, parameter set 'dg': accuracy_m"):
        accuracy_or_stored(-1.0, 12.0, "M", "dg")


# ----------------------------------------------------------------------------- information
def test_information_supersedes_sigmas_and_covariance():
    d2 = np.diff(np.eye(5), 2, axis=0)
    info = np.eye(5) / 4.0 + d2.T @ d2 / 0.01
    p = ParameterSet(tuple("abcde"), np.zeros(5), information=info)
    assert np.allclose(p.prior_covariance @ info, np.eye(5), atol=1e-9)
    assert np.allclose(p.sigmas, np.sqrt(np.diag(p.prior_covariance)))
    assert np.all(p.sigmas < 2.0)  # the smoothness tightens the amplitude's 2
    # a zero row: that parameter is free
    padded = np.zeros((6, 6))
    padded[1:, 1:] = info
    q = ParameterSet(tuple("zabcde"), np.zeros(6), information=padded)
    assert np.isinf(q.sigmas[0]) and np.isinf(q.prior_covariance[0, 0])
    assert np.all(q.prior_covariance[0, 1:] == 0)
    # kept by with_values / with_adjustable, dropped by with_sigmas
    assert q.with_values(np.ones(6)).information is q.information
    assert q.with_adjustable(["a"]).information is q.information
    assert q.with_sigmas(np.ones(6)).information is None
    # the smoothness alone is singular: refused, naming the way out
    with pytest.raises(ValueError, match="amplitude term"):
        ParameterSet(tuple("abcde"), np.zeros(5), information=d2.T @ d2)
    with pytest.raises(ValueError, match="not both"):
        ParameterSet(("a",), [0.0], covariance=[[1.0]], information=[[1.0]])
    with pytest.raises(ValueError, match="symmetric"):
        ParameterSet(("a", "b"), [0, 0], information=[[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(ValueError, match=r"must be \(2, 2\)"):
        ParameterSet(("a", "b"), [0, 0], information=[[1.0]])


def test_information_serialises_its_upper_triangle_nonzeros():
    d2 = np.diff(np.eye(50), 2, axis=0)
    info = np.eye(50) + d2.T @ d2
    p = ParameterSet([f"c{k}" for k in range(50)], np.zeros(50), information=info)
    packed = p.to_dict()["information"]
    assert len(packed["value"]) == 50 + 49 + 48  # banded: three diagonals
    assert "covariance" not in p.to_dict()
    with pytest.raises(SerializationError, match="upper triangle"):
        ParameterSet.from_dict(p.to_dict() | {"information": {"row": [1], "col": [0],
                                                             "value": [1.0]}})


@st.composite
def _information_sets(draw):
    p = draw(st.integers(1, 7))
    free = draw(st.lists(st.booleans(), min_size=p, max_size=p))
    band = draw(st.integers(0, 3))
    entries = st.floats(-3.0, 3.0, allow_nan=False)
    lower = np.zeros((p, p))
    for i in range(p):
        for j in range(max(0, i - band), i + 1):
            lower[i, j] = draw(entries)
        lower[i, i] = draw(st.floats(0.1, 5.0))
    info = lower @ lower.T
    on = ~np.array(free)
    info[~on, :] = 0.0
    info[:, ~on] = 0.0
    values = draw(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=p, max_size=p))
    adjustable = draw(st.lists(st.booleans(), min_size=p, max_size=p))
    return ParameterSet([f"p{k}" for k in range(p)], values, information=info,
                        adjustable=adjustable)


@given(_information_sets())
@settings(max_examples=60, deadline=None)
def test_information_json_round_trip(params):
    again = ParameterSet.from_dict(json.loads(json.dumps(params.to_dict(), allow_nan=False)))
    assert again == params
    assert np.array_equal(again.information, params.information)
    assert np.array_equal(again.sigmas, params.sigmas)
    assert np.array_equal(again.adjustable, params.adjustable)
