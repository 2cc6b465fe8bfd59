"""The adjustment report plots the time-dependent corrections of any model that shows them
(geoblock.models.curves.HasCorrectionCurves), with the posterior band, and nothing for a model
without them."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.adjust import Block, GroundPoints, ImagePoints, adjust
from geoblock.models import CorrectionCurve, CroppedModel, HasCorrectionCurves, ImageCorrection
from geoblock.models.curves import detrend
from geoblock.models.linescan import LinescanModel, attitude_correction
from geoblock.report import correction_curves, correction_figure, write_result
from geoblock.testing.blocks import affine_block
from geoblock.testing.synthetic import with_attitude_offsets

ROWS, COLS = 900, 300
NOISE_PX = 0.05


def wander(t: np.ndarray) -> np.ndarray:
    """(T, 3) roll and pitch sinusoids the on-board attitude lacks, radians."""
    t = np.ravel(t)
    return np.stack([3e-6 * np.sin(2 * np.pi * 2.0 * t + 0.4),
                     2e-6 * np.sin(2 * np.pi * 1.2 * t + 1.0), 0.0 * t], axis=-1)


def _true(model: LinescanModel) -> LinescanModel:
    return with_attitude_offsets(model, wander)


@pytest.fixture(scope="module")
def block() -> tuple[dict[str, LinescanModel], ImagePoints, GroundPoints]:
    """One strip, GCPs and ICPs over it, measured through the true (wandering) model."""
    rng = np.random.default_rng(27)
    onboard = LinescanModel.example((ROWS, COLS))
    true = _true(onboard)
    n = 80
    r, c = rng.uniform(0, ROWS - 1, n), rng.uniform(0, COLS - 1, n)
    h = rng.uniform(0.0, 300.0, n)
    g = true.backproject(r, c, h)
    ids = np.array([f"p{k}" for k in range(n)])
    kinds = np.where(np.arange(n) % 4 == 0, "icp", "gcp")
    ground = GroundPoints(ids, kinds, g.lon, g.lat, h, 0.05, 0.05, 0.05)
    meas = ImagePoints(ids, np.full(n, "a"), r + rng.normal(0, NOISE_PX, n),
                       c + rng.normal(0, NOISE_PX, n), NOISE_PX, NOISE_PX, kinds)
    return {"a": onboard}, meas, ground


def _adjust(block, name):
    models, meas, ground = block
    options = {"knot_lines": 60} if name == "jitter" else {}
    chosen = {k: m.with_parameter_set(name, accuracy_m=10.0, **options)
              for k, m in models.items()}
    return adjust(Block(chosen, meas, ground))


def test_the_report_plots_the_jitter_sets_correction(block, tmp_path):
    result = _adjust(block, "jitter")
    curves = correction_curves(result, "a")
    assert [c.quantity for c in curves] == ["attitude"]
    curve = curves[0]
    assert curve.values.shape == curve.sigmas.shape == (200, 3) and curve.detrended
    assert np.all(np.diff(curve.time_s) > 0)
    # the posterior band is the adjustment's: narrower than the a-priori band
    prior = result.models["a"].correction_curves()[0]
    assert np.median(curve.sigmas[:, :2]) < 0.5 * np.median(prior.sigmas[:, :2])
    # and the recovered curve is the injected wander, within a few of its sigmas
    truth = curve.compare(wander(curve.time_s))
    miss = curve.values[:, :2] - truth[:, :2]
    assert np.sqrt(np.mean(miss**2)) < 0.15 * np.sqrt(np.mean(truth[:, :2] ** 2))
    assert np.sqrt(np.mean((miss / curve.sigmas[:, :2]) ** 2)) < 3.0
    written = write_result(result, tmp_path / "out")
    assert "figure:corrections_a_attitude.png" in written
    assert (tmp_path / "out" / "corrections_a_attitude.png").stat().st_size > 1000
    md = (tmp_path / "out" / "report.md").read_text()
    assert "## Time-dependent corrections" in md
    assert "(corrections_a_attitude.png)" in md
    assert "| a | attitude | roll | µrad |" in md


def test_no_correction_figure_without_time_dependent_corrections(block, tmp_path):
    result = _adjust(block, "dg")
    assert correction_curves(result, "a") == ()
    assert result.models["a"].correction_curves() == ()
    write_result(result, tmp_path / "out")
    assert not list((tmp_path / "out").glob("corrections_*"))
    assert "Time-dependent corrections" not in (tmp_path / "out" / "report.md").read_text()


def test_the_curve_is_attitude_correction_with_the_posterior_of_the_image(block):
    result = _adjust(block, "jitter")
    names, cov = result.parameter_covariance("a")
    assert len(names) == cov.shape[0] == cov.shape[1] > 0
    model = result.models["a"]
    curve = model.correction_curves(cov, names, samples=17, detrend=False)[0]
    values, sigmas = attitude_correction(model, curve.time_s, cov, names)
    np.testing.assert_array_equal(curve.values, values)
    np.testing.assert_array_equal(curve.sigmas, sigmas)
    np.testing.assert_allclose(model.line_times.time(curve.rows), curve.time_s)
    with pytest.raises(KeyError, match="no image 'z'"):
        result.parameter_covariance("z")


def test_a_crop_shows_its_rows_of_the_scene_curve(block):
    model = block[0]["a"].with_parameter_set("jitter", accuracy_m=10.0, knot_lines=60)
    values = np.array(model.parameters.values)
    yaw = np.array([n.startswith("yaw_spline_") for n in model.parameters.names])
    values[yaw] = 1e-6 * np.sin(np.arange(yaw.sum()))
    model = model.with_parameters(values)
    crop = CroppedModel(model, (200, 0), (300, COLS))
    assert isinstance(crop, HasCorrectionCurves)
    (mine,) = crop.correction_curves(samples=11, detrend=False)
    (scene,) = model.correction_curves(rows=(200, 499), samples=11, detrend=False)
    np.testing.assert_allclose(mine.rows, np.linspace(0, 299, 11))
    np.testing.assert_array_equal(mine.values, scene.values)
    assert np.any(mine.values[:, 2] != 0)


def test_any_model_with_the_method_is_plotted(tmp_path):
    """No isinstance on a model class: a third-party model with ``correction_curves``."""

    class Curved(ImageCorrection):
        def correction_curves(self, covariance=None, names=None, *, rows=None, samples=200,
                              detrend=True):
            t = np.linspace(0.0, 2.0, samples)
            v = np.stack([np.sin(t), np.cos(t)], axis=-1)
            return (CorrectionCurve("shift", ("x", "y"), "m", t, 10 * t, 1.0, v,
                                    np.full_like(v, 0.1), False),)

    syn = affine_block((1, 2), shape=(300, 300), gcps=6, icps=3, tps=40, ictps=0)
    b = syn.block
    models = {i: Curved(m.model, order=1) for i, m in b.models.items()}
    result = adjust(Block(models, b.measurements, b.ground, b.dem, b.dem_sigma_m))
    written = write_result(result, tmp_path / "out")
    assert {k for k in written if k.startswith("figure:corrections_")} == {
        f"figure:corrections_{i}_shift.png" for i in result.models}


def test_the_truth_is_detrended_like_the_curve():
    t = np.linspace(-1.0, 1.0, 50)
    wave = np.stack([np.sin(3 * t), np.cos(2 * t)], axis=-1)
    curve = CorrectionCurve("attitude", ("roll", "pitch"), "rad", t, np.arange(50.0), 0.0,
                            detrend(t, wave), np.full((50, 2), 1e-7), True)
    truth = wave + 5.0 + 2.0 * t[:, None]  # plus a level and a trend the curve lacks
    np.testing.assert_allclose(curve.compare(truth), curve.values, atol=1e-12)
    fig = correction_figure(curve, truth)
    labels = [line.get_label() for ax in fig.axes for line in ax.get_lines()]
    rms = [float(label.split(": ")[1].split()[0]) for label in labels
           if label.startswith("truth (recovered − truth")]
    assert len(rms) == 2 and max(rms) < 1e-6, labels
    with pytest.raises(Exception, match="truth of shape"):
        curve.compare(truth[:, :1])
