"""The jitter study (geoblock_papers.jitter): on the teo2010-spot5 strips with a measured
attitude wander, the linescan model's "jitter" set recovers the wander the "dg" set leaves,
brings the residuals to the pointing noise, and its posterior predicts the ICP error."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from geoblock_papers import jitter
from geoblock_papers.report import Report

from geoblock.models.linescan import LinescanModel

#: a lighter design than the study's (fewer points): seconds
DESIGN = replace(jitter.DESIGN, icp=20, tp=100)


@pytest.fixture(scope="module")
def scene() -> jitter.JitterScene:
    return jitter.make_scene(DESIGN)


def test_true_correction_reads_back_an_injected_rotation():
    model = LinescanModel.example((200, 100))
    t = np.linspace(-0.3, 0.3, 7)
    angles = np.stack([2e-6 * np.sin(t), -3e-6 * np.cos(t), 1e-6 * t], axis=-1)
    from geoblock.testing.synthetic import with_attitude_offsets

    span = np.diff(model.attitude.valid_span_s).item()
    true = with_attitude_offsets(
        model, lambda ts: np.stack([2e-6 * np.sin(ts), -3e-6 * np.cos(ts), 1e-6 * ts], axis=-1),
        step_s=span / 2000)
    np.testing.assert_allclose(jitter.true_correction(model, true, t), angles, atol=2e-9)


def test_the_jitter_set_recovers_the_wander(scene):
    """Precise points (0.1 px, GCPs to 0.3 m): the wander is what the dg set leaves."""
    precise = replace(DESIGN, pointing_px=0.1, survey_m=0.3)
    out = jitter.seed_outcome(scene, 3, ("dg", "jitter"), precise).values
    dg, jit = out["dg/miss_arcsec/roll+pitch"], out["jitter/miss_arcsec/roll+pitch"]
    # dg leaves the whole wander (its detrended correction is zero): the injected size
    assert dg == pytest.approx(math.sqrt(np.mean([out[f"dg/wander_rms_arcsec/{k}"] ** 2
                                                  for k in scene.images])), rel=1e-9)
    assert dg > 0.3, out
    assert jit < 0.6 * dg, (jit, dg)
    assert out["jitter/miss_m"] < 0.6 * out["dg/miss_m"]
    assert out["jitter/image_m"] < 0.7 * out["dg/image_m"]
    # residuals: at the noise with the jitter set, well above it without
    assert 0.8 < out["jitter/sigma0"] < 1.2, out["jitter/sigma0"]
    assert out["dg/sigma0"] > 2.0, out["dg/sigma0"]


def test_the_study_reports_a_to_e(scene, tmp_path, monkeypatch):
    monkeypatch.setattr(jitter, "make_scene", lambda design, variant: scene)
    report = Report("jitter", jitter.TITLE, jitter.CITATION, variant="small", seeds=(0,),
                    outdir=tmp_path)
    jitter.run(report, full=False, seeds=(0,), design=DESIGN)
    paths = report.write(seconds=1.0)
    md = paths["report"].read_text()
    for part in ("(a)-(c)", "(d) ICP RMSE", "(e) The recovered correction", "no GCP",
                 "precise"):
        assert part in md, part
    assert (tmp_path / "jitter_correction_strip1.png").stat().st_size > 1000
    results = json.loads(paths["results"].read_text())
    ratio = results["results"]["posterior_ratio"]["jitter_pooled"]
    # one seed: loose; the 20-seed study measures it to within a few per cent
    assert 0.7 < ratio < 1.4, ratio
    values = results["results"]["per_seed"]["0"]
    assert values["jitter-nogcp/miss_arcsec/roll+pitch"] < values[
        "dg-nogcp/miss_arcsec/roll+pitch"]
    assert math.isfinite(values["jitter-nogcp/sigma0"])
