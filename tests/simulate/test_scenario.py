"""Scenarios: presets, the TOML form and its errors, run_scenario's files, truth and seeds."""

from __future__ import annotations

import csv
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.errors import NotGeoreferencedWarning

import geoblock
from geoblock.io import open_dem, open_image, read_block, read_points
from geoblock.io.blocks import dumps_toml
from geoblock.simulate.demo import demo_scenario
from geoblock.simulate.scenario import (
    PRESETS,
    Scenario,
    ScenarioError,
    load_scenario,
    preset,
    preset_dict,
    read_scenario,
    run_scenario,
    scenario_from_dict,
    scenario_to_dict,
)
from geoblock.simulate.sensors import SPOT5_STRIPS, onboard_error


def _tiny_aguilar(seed: int = 7) -> Scenario:
    data = preset_dict("aguilar2007-quickbird", "small")
    data["images"][0]["scale"] = 160  # ~170 x 170 px at 99 m
    data["terrain"]["resolution_m"] = 100.0
    data["dems"] = [{"name": "dem200", "spacing_m": 200.0, "rmse_z": 5.82}]
    data["points"].update(gcp=9, icp=20)
    data["seed"] = seed
    return scenario_from_dict(data, "test:aguilar-tiny")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The demo's tiny three-strip block (200 x 200 px strips), simulated once."""
    out = tmp_path_factory.mktemp("tiny")
    messages: list[str] = []
    result = run_scenario(demo_scenario("tiny"), out, progress=messages.append)
    return result, messages


# ---------------------------------------------------------------------------- presets
@pytest.mark.parametrize("name", list(PRESETS))
@pytest.mark.parametrize("variant", ["small", "full"])
def test_presets_parse(name, variant):
    sc = preset(name, variant)
    assert sc.source == f"preset:{name}/{variant}"
    assert sc.dems and sc.images
    # the small variant keeps the footprint: same GSD x columns as the full one
    full = preset(name, "full")
    for a, b in zip(sc.images, full.images, strict=True):
        assert a.spec.gsd_m * a.spec.shape[1] == pytest.approx(b.spec.gsd_m * b.spec.shape[1],
                                                                rel=0.01)


def test_preset_values_follow_the_papers():
    teo = preset("teo2010-spot5", "full")
    assert [im.spec.incidence_deg for im in teo.images] == [5.2, 5.7, -14.8]
    assert [im.spec.shape for im in teo.images] == [(24000, 24000)] * 3
    assert teo.terrain.relief == (0.0, 3800.0) and teo.terrain.kind == "ridged"
    assert [(d.spacing_m) for d in teo.dems] == [40.0]
    assert teo.points.gcp == 9 and teo.points.tp == (13, 32) and teo.points.ictp[0] > 0
    qb = preset("aguilar2007-quickbird", "full")
    assert qb.images[0].spec.gsd_m == 0.62 and qb.images[0].spec.roll_deg == 8.0
    assert qb.terrain.relief == (50.0, 850.0)
    assert [(d.spacing_m, d.rmse_z) for d in qb.dems] == [(2.0, 0.31), (5.0, 1.75), (20.0, 5.82)]
    assert (qb.points.gcp, qb.points.icp, qb.points.design, qb.points.cells) == (
        45, 79, "stratified", 3)
    chen = preset("chen1993-spot1a", "full")
    assert chen.points.gcp == 21 and chen.points.icp > 0
    assert chen.terrain.relief[1] - chen.terrain.relief[0] == 950.0
    assert chen.images[0].spec.shape == (6000, 6000)


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ScenarioError, match="teo2010-spot5.*aguilar2007-quickbird.*chen1993"):
        load_scenario("nope")
    with pytest.raises(ScenarioError, match="variant"):
        preset("teo2010-spot5", "huge")


# ---------------------------------------------------------------------------- TOML
def test_toml_round_trip(tmp_path):
    sc = preset("teo2010-spot5", "small", seed=5)
    path = tmp_path / "s.toml"
    path.write_text(dumps_toml(scenario_to_dict(sc)))
    back = read_scenario(path)
    assert back.replace(source=sc.source) == sc
    assert [im.spec for im in back.images] == [im.spec for im in sc.images]
    other = sc.with_seed(6)
    assert other.seed == 6 and other.images[0].spec.seed != sc.images[0].spec.seed
    assert other.replace(seed=5, images=sc.images) == sc


def test_file_starting_from_a_preset(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('preset = "teo2010-spot5"\nseed = 3\n[points]\ngcp = 4\n'
                    '[terrain]\nrelief = [100.0, 2000.0]\n')
    sc = load_scenario(path, variant="full")
    assert sc.seed == 3 and sc.points.gcp == 4 and sc.points.icp == 20  # merged
    assert sc.terrain.relief == (100.0, 2000.0) and sc.terrain.kind == "ridged"
    assert sc.images[0].spec.shape == (24000, 24000)
    # a different seed re-seeds the sensors
    assert load_scenario(path, seed=4).images[0].spec.seed != sc.images[0].spec.seed


def test_image_overrides_and_custom_sensor():
    data = {
        "seed": 1,
        "images": [
            {"id": "a", "preset": "spot5-strip1", "scale": 40, "onboard_rmse_m": 5.0},
            {"id": "b", "name": "custom", "altitude_m": 700e3, "inclination_deg": 98.0,
             "ascending": True, "centre_lon": 10.0, "centre_lat": 45.0, "gsd_m": 20.0,
             "shape": [300, 400]},
        ],
        "dems": [{"name": "dem", "spacing_m": 30.0, "rmse_z": 2.0}],
    }
    sc = scenario_from_dict(data, "x.toml")
    a, b = sc.images
    assert a.spec.onboard_rmse_m == 5.0 and a.spec.gsd_m == SPOT5_STRIPS[0].gsd_m * 40
    assert a.spec.name == "a" and b.spec.name == "custom" and b.spec.shape == (300, 400)


@pytest.mark.parametrize("change, key, message", [
    ({"colour": 1}, "colour", "unknown key"),
    ({"seed": "one"}, "seed", "an integer"),
    ({"seed": -1}, "seed", ">= 0"),
    ({"images": []}, "images", "at least one"),
    ({"images": [{"id": "a", "preset": "landsat"}]}, r"images\[0\]\.preset", "spot5-strip1"),
    ({"images": [{"id": "a", "preset": "quickbird", "focal": 1.0}]}, r"images\[0\]\.focal",
     "unknown key"),
    ({"images": [{"id": "a", "gsd_m": 2.0}]}, r"images\[0\]", "altitude_m"),
    ({"images": [{"id": "a", "preset": "quickbird", "gsd_m": -1.0}]}, r"images\[0\]", "gsd_m"),
    ({"images": [{"id": "a/b", "preset": "quickbird"}]}, r"images\[0\]\.id", "file-name"),
    ({"terrain": {"kind": "alpine"}}, "terrain.kind", "ridged, fractal"),
    ({"terrain": {"relief": [5.0, 1.0]}}, "terrain.relief", "high"),
    ({"terrain": {"crs": "EPSG:nope"}}, "terrain.crs", "not a CRS"),
    ({"dems": [{"name": "d", "spacing_m": 0.0, "rmse_z": 1.0}]}, r"dems\[0\]\.spacing_m", "> 0"),
    ({"points": {"gcp": 2.5}}, "points.gcp", "an integer"),
    ({"points": {"tp": [5, 2]}}, "points.tp", "high must be"),
    ({"points": {"design": "grid"}}, "points.design", "stratified, random"),
    ({"render": {"dtype": "float32"}}, "render.dtype", "uint8, uint16"),
    ({"variant": "small"}, "variant", "preset"),
])
def test_errors_name_the_file_and_the_key(change, key, message):
    data = preset_dict("chen1993-spot1a", "small")
    data.update(change)
    with pytest.raises(ScenarioError, match=rf"^my\.toml: {key}: .*{message}"):
        scenario_from_dict(data, "my.toml")


def test_file_errors(tmp_path):
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("seed = = 1\n")
    with pytest.raises(ScenarioError, match="bad.toml: not a valid TOML"):
        load_scenario(bad)
    plain = tmp_path / "plain.toml"
    plain.write_text(dumps_toml(preset_dict("chen1993-spot1a")))
    with pytest.raises(ScenarioError, match="--variant applies to presets"):
        load_scenario(plain, variant="full")


# ---------------------------------------------------------------------------- running
def test_every_file_opens(tiny):
    result, messages = tiny
    out = result.outdir
    assert messages and messages[-1].startswith("done in")
    tifs = sorted(out.rglob("*.tif"))
    assert {p.relative_to(out).as_posix() for p in tifs} == {
        "terrain/truth.tif", "terrain/dem200.tif",
        "images/strip1.tif", "images/strip2.tif", "images/strip3.tif"}
    for path in tifs:
        with warnings.catch_warnings():  # raw images have no georeferencing, by design
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            with rasterio.open(path) as ds:
                assert ds.read(1).shape == (ds.height, ds.width)
                assert (ds.crs is None) == (path.parent.name == "images")
    for name in ("truth", "dem200"):
        dem = open_dem(str(out / "terrain" / f"{name}.tif"))
        lo, hi = dem.height_range()
        assert -50 < lo < hi < 3850
    for image_id, sensor in result.sensors.items():
        source = open_image(out / "images" / f"{image_id}.tif")
        assert source.shape == sensor.spec.shape
        for kind in ("true", "onboard"):
            model = geoblock.open_model(out / "images" / f"{image_id}_{kind}.json")
            assert model.shape == sensor.spec.shape
    for name in ("ground", "image", "truth"):
        assert len(read_points(out / "points" / f"{name}.csv")["id"]) > 0
    block = read_block(out / "block.toml")
    assert [im.id for im in block.images] == ["strip1", "strip2", "strip3"]
    assert block.images[0].model == out / "images" / "strip1_onboard.json"
    assert block.images[0].raster == out / "images" / "strip1.tif"
    assert Path(block.dem.source) == out / "terrain" / "dem200.tif"
    for png in (out / "report").glob("*.png"):
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert {p.name for p in (out / "report").glob("*.png")} == {
        "errors_strip1.png", "errors_strip2.png", "errors_strip3.png"}
    text = (out / "report" / "report.md").read_text()
    assert "## Accuracy of the on-board models" in text and "strip2 & strip3" in text
    # the scenario written out runs as is
    again = read_scenario(out / "scenario.toml")
    assert again.replace(source="") == result.scenario.replace(source="")
    assert tomllib.loads((out / "scenario.toml").read_text())["seed"] == result.scenario.seed


def test_true_model_reprojects_the_noise_free_points(tiny):
    result, _ = tiny
    out = result.outdir
    with open(out / "points" / "truth.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    truth = {k: np.array([r[k] for r in rows]) for k in ("image",)}
    truth |= {k: np.array([float(r[k]) for r in rows])
              for k in ("lon_true", "lat_true", "h_true", "row_true", "col_true")}
    for image_id in result.sensors:
        model = geoblock.open_model(out / "images" / f"{image_id}_true.json")
        sel = np.asarray(truth["image"]) == image_id
        assert sel.sum() > 10
        row, col = model.project(np.asarray(truth["lon_true"])[sel],
                                 np.asarray(truth["lat_true"])[sel],
                                 np.asarray(truth["h_true"])[sel])
        assert np.max(np.abs(row - np.asarray(truth["row_true"])[sel])) < 1e-6
        assert np.max(np.abs(col - np.asarray(truth["col_true"])[sel])) < 1e-6


def test_onboard_errors_have_the_requested_statistics(tiny):
    result, _ = tiny
    out = result.outdir
    for image_id, sensor in result.sensors.items():
        true = geoblock.open_model(out / "images" / f"{image_id}_true.json")
        onboard = geoblock.open_model(out / "images" / f"{image_id}_onboard.json")
        grid = onboard_error(true, onboard, h=sensor.spec.centre_h)
        assert grid.rmse == pytest.approx(sensor.spec.onboard_rmse_m, rel=1e-3)
        # at the GCPs and ICPs (on the terrain, not at the centre height): same magnitude
        stats = result.onboard.select(image=image_id).stats()
        assert stats.rmse_2d == pytest.approx(sensor.spec.onboard_rmse_m, rel=0.3)
    assert result.ictp is not None and len(result.ictp) >= 8


def test_images_show_the_texture(tiny):
    result, _ = tiny
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(result.files["image:strip2"]) as ds:
            pixels = ds.read(1)
    assert (pixels > 0).mean() > 0.99 and pixels.std() > 20


def test_same_seed_same_files_other_seed_other_files(tiny, tmp_path):
    result, _ = tiny
    again = run_scenario(demo_scenario("tiny"), tmp_path / "again")
    files = sorted(p.relative_to(result.outdir) for p in result.outdir.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(again.outdir) for p in again.outdir.rglob("*")
                           if p.is_file())
    for rel in files:
        if rel.name != "timings.json":  # the only file with times in it
            assert (result.outdir / rel).read_bytes() == (again.outdir / rel).read_bytes(), rel
    other = run_scenario(demo_scenario("tiny", seed=99), tmp_path / "other", render=False)
    for rel in ("terrain/truth.tif", "terrain/dem200.tif", "points/truth.csv",
                "images/strip1_onboard.json"):
        assert (result.outdir / rel).read_bytes() != (other.outdir / rel).read_bytes(), rel
    assert "images not rendered (render disabled)" in other.notes
    assert not (other.outdir / "images" / "strip1.tif").exists()


def test_single_image_with_distance_plot_and_render_limit(tmp_path):
    sc = _tiny_aguilar()
    sc = sc.replace(render=sc.render.__class__(max_pixels=1000))
    result = run_scenario(sc, tmp_path)
    assert result.ictp is None
    assert any("not rendered" in n and "max_pixels" in n for n in result.notes)
    assert (tmp_path / "report" / "residual_vs_distance.png").is_file()
    assert "not rendered" in (tmp_path / "report" / "report.md").read_text()
    assert not (tmp_path / "report" / "ictp_accuracy.csv").exists()
    assert result.points.count("gcp") == 9 and result.points.count("icp") == 20


def test_aguilar_small_reproduces_the_rpcv0_drift_with_distance(tmp_path):
    """Aguilar et al. Fig. 4: after an RPCV-0-style shift fitted to all 45 GCPs the ICP error
    grows with the distance from the image centre (the on-board along-track drift); RPCV-1
    absorbs it; the RMSE-vs-GCPs study is written."""
    from geoblock.adjust.statistics import distance_from_image_centre
    from geoblock.simulate.scenario import _refinement_points
    from geoblock.simulate.study import refined_errors

    sc = preset("aguilar2007-quickbird", "small")
    assert sc.report.distance_plot and sc.report.gcp_study
    result = run_scenario(sc, tmp_path, render=False)
    sensor = result.sensors["quickbird"]
    gcps, icps = _refinement_points(result.points, "quickbird")
    assert len(gcps) == 45
    d = distance_from_image_centre(sensor.true_model, icps.lon, icps.lat, icps.h)
    e0 = refined_errors(sensor.onboard_model, gcps, icps, 0)
    e1 = refined_errors(sensor.onboard_model, gcps, icps, 1)
    slope, _ = np.polyfit(d / 1000.0, e0, 1)
    r2 = np.corrcoef(d, e0)[0, 1] ** 2
    assert slope > 0.3 and r2 > 0.2  # m/km; measured 1.03 m/km, R^2 0.35 (the paper: 0.37)
    assert np.sqrt(np.mean(e1**2)) < 0.2 * np.sqrt(np.mean(e0**2))
    report = (tmp_path / "report" / "report.md").read_text()
    assert "ICP accuracy against the number of GCPs" in report
    assert (tmp_path / "report" / "rmse_vs_gcps_quickbird.png").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PRESETS))
def test_small_presets_run(name, tmp_path):
    # (their time and memory are measured in benchmarks/bench_simulate.py)
    result = run_scenario(preset(name, "small"), tmp_path, render=False)
    assert (tmp_path / "report" / "report.md").is_file()
    sc = result.scenario
    assert result.points.count("gcp") >= sc.points.gcp * len(sc.images)
    for sensor in result.sensors.values():
        assert sensor.onboard_error().rmse == pytest.approx(sensor.spec.onboard_rmse_m, rel=1e-3)
