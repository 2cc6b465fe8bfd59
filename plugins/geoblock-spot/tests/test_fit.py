"""fit_chenlee's interior geometry: the source model's own (line period, angular pixel), so
that the mba set's a-priori sigmas (scene duration, swath) fit the sensor; a warning or a
refusal when the source does not tell."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geoblock_spot.chenlee import SPOT1A_INTERIOR, ChenLeeModel, Interior
from geoblock_spot.fit import InteriorWarning, fit_chenlee, source_interior

import geoblock
from geoblock.errors import GeoblockWarning, ParameterSetError
from geoblock.simulate.sensors import SPOT5_STRIPS_SMALL, simulate_sensor
from geoblock.testing.synthetic import ConstantVelocityPushbroom


@pytest.fixture(scope="module")
def spot5_strip():
    """The onboard model of a simulated SPOT-5 strip, 600 x 600 px of 100 m (line period
    ~15.2 ms, so ~9.1 s of scene; SPOT 1A's 1.5 ms would make it 0.9 s)."""
    return simulate_sensor(SPOT5_STRIPS_SMALL[0]).onboard_model


def test_fit_takes_the_interior_of_a_spot5_like_linescan_model(spot5_strip):
    m = spot5_strip
    accuracy = m.location_accuracy_m
    period = m.line_times.line_period_s
    duration = m.shape[0] * period
    assert 9.0 < duration < 9.3
    fit = fit_chenlee(m, location_accuracy_m=accuracy)
    assert fit.interior_source == "source"
    assert fit.model.interior.line_period_s == period
    assert fit.model.scene_duration_s == pytest.approx(duration, rel=1e-12)
    # the angular pixel is the strip's (gsd / altitude): Sy comes out 1
    spec = SPOT5_STRIPS_SMALL[0]
    interior = fit.model.interior
    assert interior.pixel_size_m / interior.focal_length_m == pytest.approx(
        spec.gsd_m / spec.altitude_m, rel=1e-9)
    assert fit.model.coefficients[18] == pytest.approx(1.0, abs=1e-4)
    assert fit.max_px < 0.01
    # mba sigmas: orbit s, s / T, s / T^2 (Teo et al.'s scaling with the scene duration)
    sigmas = fit.model.parameters.sigmas
    np.testing.assert_allclose(sigmas[:3], [accuracy, accuracy / duration,
                                            accuracy / duration**2], rtol=1e-12)
    np.testing.assert_allclose(sigmas, fit.model.mba_sigmas(accuracy), rtol=1e-12)
    # half swath W = H * (cols / 2) * angular pixel: d_sy's sigma s / W ~ s / 30 km
    assert 25e3 < accuracy / sigmas[18] < 35e3


def test_a_given_interior_is_kept(spot5_strip):
    """The old default, SPOT 1A's interior, still works when asked for: the geometry fits as
    well (Sy and the time polynomials absorb it) but the scene lasts 0.9 s."""
    fit = fit_chenlee(spot5_strip, interior=SPOT1A_INTERIOR, location_accuracy_m=33.6)
    assert fit.interior_source == "given" and fit.model.interior == SPOT1A_INTERIOR
    assert fit.model.scene_duration_s == pytest.approx(600 * 1.5e-3)
    assert fit.max_px < 0.01
    assert fit.model.coefficients[18] == pytest.approx(10.0, rel=1e-2)  # 10x SPOT 1A pixels


def test_a_spot1a_like_source_gets_spot1a_s_interior():
    """A 6000 x 6000 linescan model of 13 um pixels behind 1.082 m, 1.5 ms per line,
    rolled 10 degrees: the derived interior is SPOT 1A's."""
    from geoblock.models import linescan as ls
    c = np.arange(6000) - 2999.5
    look = ls.LookDirections.from_tan_angles(np.zeros(6000), c * 13e-6 / 1.082)
    tilted = ls.LookDirections(look.vectors @ ls.rotation_xyz(math.radians(10.0), 0.0, 0.0).T)
    base = ls.LinescanModel.example()
    for directions in (look, tilted):
        model = ls.LinescanModel(
            (6000, 6000), base.ephemeris, base.attitude, directions,
            ls.LineTimes(2999.5, 0.0, 1.5e-3))
        interior = source_interior(model)
        assert interior is not None
        assert interior.line_period_s == 1.5e-3
        assert interior.focal_length_m == SPOT1A_INTERIOR.focal_length_m
        assert interior.pixel_size_m == pytest.approx(13e-6, rel=1e-12)


def test_a_chen_lee_source_gives_its_interior():
    interior = Interior(6.5e-6, 1.082, 0.75e-3)
    model = ChenLeeModel.table1(interior=interior)
    assert source_interior(model) == interior


def test_a_source_without_an_interior_warns_or_refuses():
    source = ConstantVelocityPushbroom.example(roll=0.1)
    assert source_interior(source) is None
    with pytest.warns(InteriorWarning, match="synthetic-pushbroom.*SPOT 1A"):
        fit = fit_chenlee(source)
    assert issubclass(InteriorWarning, GeoblockWarning)
    assert fit.interior_source == "assumed SPOT 1A" and fit.model.interior == SPOT1A_INTERIOR
    assert fit.max_px < 1e-6  # the geometry is right all the same
    with pytest.raises(ParameterSetError, match="synthetic-pushbroom.*interior=Interior"):
        fit_chenlee(source, location_accuracy_m=10.0)


@pytest.mark.parametrize(("name", "rows", "period_s", "pixel_m"), [
    ("SPOT1.DIM", 6000, 1.504e-3, 13e-6), ("SPOT5.DIM", 12000, 0.752e-3, 6.5e-6),
])
def test_the_interior_of_real_dimap_models(data_dir, name, rows, period_s, pixel_m):
    """SPOT 1 (HRV panchromatic, 27 degrees off nadir: the mirror is in the look directions)
    and SPOT 5 (HRG 5 m) DIMAP products: their CCD pitch behind 1.082 m and line period,
    ~9 s of scene."""
    path = data_dir / "cosicorr3d" / "test_dataset" / name
    if not path.exists():
        pytest.skip(f"{path} not in the test data")
    model = geoblock.open_model(path)
    interior = source_interior(model)
    assert model.shape[0] == rows
    assert interior.line_period_s == pytest.approx(period_s, rel=1e-5)
    assert interior.pixel_size_m == pytest.approx(pixel_m, rel=3e-3)
    assert rows * interior.line_period_s == pytest.approx(9.02, abs=0.01)
