"""Ground control from a reference orthoimage (geoblock.match.reference) on simulated scenes:
the reference is rendered from the simulator's ground texture (the truth) at 10 m GSD,
shaded by the true terrain as the images are, and misregistered by a known shift. The
control points must carry that shift (their ground is where the reference shows the
feature), and their image positions must be where the TRUE model sees the true ground."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import rasterio
import rasterio.errors
from affine import Affine

import geoblock
from geoblock import coords
from geoblock.errors import MatchError
from geoblock.match import ReferenceOptions, match_reference, reference_sigmas
from geoblock.match.reference import CE90_FACTOR
from geoblock.simulate.render import _shade
from geoblock.simulate.scenario import read_scenario, scenario_from_dict
from geoblock.simulate.scene import scene_sensors, scene_texture
from geoblock.workflows import run_scenario

SHIFT = (3.0, -4.0)  # east, north metres: where the reference puts the ground, minus truth
DEG_M = math.radians(1.0) * 6378137.0


def scenario(gsd: float, n: int, images: int, seed: int, texture_scale: float) -> dict:
    image = {"preset": "spot5-strip1", "centre_lon": 120.95, "shape": [n, n], "gsd_m": gsd}
    views = [{"id": "a", **image, "incidence_deg": 12.0},
             {"id": "b", **image, "incidence_deg": -12.0, "epoch": "2003-06-23T02:40:00Z"}]
    return {
        "name": "reference", "seed": seed, "method": "dg", "images": views[:images],
        "terrain": {"kind": "ridged", "relief": [100.0, 400.0], "resolution_m": 10.0,
                    "vertical": "ellipsoid", "margin_m": 300.0},
        "dems": [{"name": "dem", "spacing_m": 20.0, "rmse_z": 5.0}],
        "points": {"gcp": 4, "icp": 0, "tp": [0, 0], "ictp": [0, 0], "sigma_px": 0.3},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": texture_scale},
        "report": {"distance_plot": False, "gcp_study": False},
    }


def render_reference(out, path, *, gsd=10.0, shift=SHIFT, crs=None, dtype="uint16",
                     margin_m=800.0, offset_m=(0.0, 0.0), rows_share=1.0):
    """A reference ortho of the scene in ``out``: the ground texture times the true terrain's
    shade, averaged over 4 x 4 samples per pixel, placed ``shift`` metres off the truth."""
    sc = read_scenario(out / "scenario.toml")
    sensors = scene_sensors(sc)
    texture = scene_texture(sc, sensors)
    truth = geoblock.open_dem(out / "terrain" / "truth.tif")
    lons, lats = [], []
    for s in sensors.values():
        fp = s.true_model.footprint()
        lons += list(fp.lon)
        lats += list(fp.lat)
    zone = int((np.mean(lons) + 180) // 6) + 1
    crs = crs or f"EPSG:{32600 + zone}"
    x, y = coords.transformer("EPSG:4326", crs).transform(lons, lats)
    x0 = math.floor((min(x) - margin_m) / gsd) * gsd + offset_m[0]
    y1 = math.ceil((max(y) + margin_m) / gsd) * gsd + offset_m[1]
    cols = int(round((max(x) - min(x) + 2 * margin_m) / gsd))
    rows = int(round((max(y) - min(y) + 2 * margin_m) / gsd * rows_share))
    k = 4
    sub = (np.arange(k) + 0.5) / k
    r = np.arange(rows)[:, None, None, None] + sub[None, None, :, None]
    c = np.arange(cols)[None, :, None, None] + sub[None, None, None, :]
    ex, ny = np.broadcast_arrays(x0 + c * gsd, y1 - r * gsd)
    lon, lat = coords.transformer(crs, "EPSG:4326").transform(ex, ny)
    lat = np.asarray(lat) - shift[1] / DEG_M
    lon = np.asarray(lon) - shift[0] / (DEG_M * np.cos(np.radians(lat)))
    light = 0.3 + 0.7 * _shade(truth, lon, lat, 315.0, 45.0) / math.sin(math.radians(45.0))
    value = (np.asarray(texture(lon, lat)) * light).mean(axis=(2, 3))
    if dtype == "uint16":
        data, nodata = np.clip(np.round(1 + value * 65534), 1, 65535).astype("uint16"), 0
    else:
        data, nodata = value.astype(dtype), float("nan")
    with rasterio.open(path, "w", driver="GTiff", width=cols, height=rows, count=1,
                       dtype=data.dtype, crs=crs, transform=Affine(gsd, 0, x0, 0, -gsd, y1),
                       nodata=nodata) as dst:
        dst.write(data, 1)
    return path


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """Two 600 x 600 px views at 2.5 m (incidences +-12 degrees) and a 10 m reference."""
    out = tmp_path_factory.mktemp("reference-scene")
    run_scenario(scenario_from_dict(scenario(2.5, 600, 2, 5, 1.0)), out)
    render_reference(out, out / "ref_10.tif")
    return out


def images(out, ids=("a", "b")):
    return {i: (out / "images" / f"{i}_onboard.json", out / "images" / f"{i}.tif")
            for i in ids}


def ground_errors(out, control, image_id):
    """East/north (m) of the control points' ground minus the true ground of their image
    measurements (the TRUE model on the TRUE terrain), and the distance (pixels) from each
    image measurement to the TRUE model's projection of the true ground point."""
    truth = geoblock.open_dem(out / "terrain" / "truth.tif")
    model = geoblock.open_model(out / "images" / f"{image_id}_true.json")
    g, m = control.ground, control.measurements
    sel = m["image"] == image_id
    assert np.array_equal(g["id"][sel], m["id"][sel])
    gr, status = geoblock.localize(model, m["row"][sel], m["col"][sel], truth, warn=False)
    assert (status == 0).all()
    de, dn, _ = coords.enu_offsets(gr.lon, gr.lat, gr.h, g["lon"][sel], g["lat"][sel],
                                   g["h"][sel])
    # the true ground point: the control's position minus the reference's shift
    lat = g["lat"][sel] - SHIFT[1] / DEG_M
    lon = g["lon"][sel] - SHIFT[0] / (DEG_M * np.cos(np.radians(g["lat"][sel])))
    ic = model.project(lon, lat, truth.height(lon, lat))
    return de, dn, np.hypot(ic.row - m["row"][sel], ic.col - m["col"][sel])


@pytest.fixture(scope="module")
def control(scene):
    return match_reference(images(scene), scene / "ref_10.tif",
                           geoblock.open_dem(scene / "terrain" / "dem.tif"),
                           reference_accuracy_ce90_m=5.0, dem_sigma_m=5.0)


def test_control_points_carry_the_reference_shift(scene, control):
    for image_id in ("a", "b"):
        stats = control.image(image_id)
        assert stats.status == "matched"
        assert stats.reduction == 4  # 2.5 m pixels averaged 4 x 4 for a 10 m reference
        de, dn, _ = ground_errors(scene, control, image_id)
        assert de.size >= 40, stats.summary()
        # the median within 0.15 reference pixels of the shift the reference was given
        assert abs(np.median(de) - SHIFT[0]) < 1.5, (np.median(de), np.median(dn))
        assert abs(np.median(dn) - SHIFT[1]) < 1.5, (np.median(de), np.median(dn))
        # every kept match within one reference pixel of the truth
        assert np.mean(np.hypot(de - SHIFT[0], dn - SHIFT[1]) < 10.0) >= 0.95


def test_image_positions_are_where_the_true_model_sees_the_feature(scene, control):
    for image_id in ("a", "b"):
        _, _, err = ground_errors(scene, control, image_id)
        # image pixels of 2.5 m against a 10 m reference: 0.6 px is 0.15 reference pixels
        assert np.median(err) < 0.6, np.percentile(err, [50, 90])
        assert np.percentile(err, 90) < 1.5, np.percentile(err, [50, 90])


def test_rows_and_sigmas(scene, control):
    g, m = control.ground, control.measurements
    assert list(g) == ["id", "kind", "source", "lon", "lat", "h", "sigma_e", "sigma_n",
                       "sigma_h", "sigma_shift_e", "sigma_shift_n", "sigma_shift_h"]
    assert list(m) == ["id", "image", "row", "col", "sigma", "kind"]
    assert set(g["kind"]) == {"gcp"} and set(g["source"]) == {"reference:ref_10.tif"}
    assert np.unique(g["id"]).size == g["id"].size
    dem = geoblock.open_dem(scene / "terrain" / "dem.tif")
    assert np.allclose(g["h"], dem.height(g["lon"], g["lat"]))
    for stats in control.images:
        sel = m["image"] == stats.image
        own = stats.sigma_match_px * 10.0
        assert np.allclose(g["sigma_e"][sel], own)
        assert np.allclose(g["sigma_n"][sel], own)
        # the reference's CE90 is one error common to all its points
        assert np.allclose(g["sigma_shift_e"][sel], 5.0 / CE90_FACTOR)
        assert np.allclose(g["sigma_shift_n"][sel], 5.0 / CE90_FACTOR)
        assert np.all(g["sigma_shift_h"][sel] == 0.0)
        total = math.hypot(own, 5.0 / CE90_FACTOR)
        assert (g["sigma_h"][sel] >= 5.0).all() and (g["sigma_h"][sel] < 5.0 + total).all()
        assert stats.counts()["kept"] == sel.sum()
        # the image's misregistration against the reference: its onboard model's error
        # plus the reference's shift, a few reference pixels
        assert 1.0 < math.hypot(*stats.shift_px) < 8.0


def test_sigma_formula():
    s, h, common = reference_sigmas(8.5, 0.2, 10.0, 5.0, [0.0, 0.3])
    assert s == pytest.approx(2.0)  # the matching's 0.2 px of 10 m
    assert common == pytest.approx(8.5 / 2.1460)
    assert h[0] == pytest.approx(5.0)
    assert h[1] == pytest.approx(math.sqrt(25.0 + 0.09 * (s**2 + common**2)))
    # a stated local (point-to-point) accuracy joins each point's own sigma, not the common one
    s2, _, common2 = reference_sigmas(8.5, 0.2, 10.0, 5.0, [0.0], local_accuracy_ce90_m=3.0)
    assert s2 == pytest.approx(math.hypot(3.0 / 2.1460, 2.0))
    assert common2 == common
    # the CE90 factor is the circular normal's: P(r <= 2.1460 sigma) = 0.9
    assert 1 - math.exp(-(CE90_FACTOR**2) / 2) == pytest.approx(0.9, abs=1e-4)


def test_geographic_float_reference_with_nan_nodata(scene, tmp_path):
    ref = render_reference(scene, tmp_path / "geo.tif", gsd=1e-4, crs="EPSG:4326",
                           dtype="float32", margin_m=0.01)
    result = match_reference(images(scene, ("a",)), ref,
                             geoblock.open_dem(scene / "terrain" / "dem.tif"),
                             reference_accuracy_ce90_m=5.0, dem_sigma_m=5.0)
    assert 9.0 < result.gsd_reference_m < 11.0  # 1e-4 degrees at 24 N
    de, dn, _ = ground_errors(scene, result, "a")
    assert de.size >= 30
    assert abs(np.median(de) - SHIFT[0]) < 1.5 and abs(np.median(dn) - SHIFT[1]) < 1.5


def test_partial_and_missing_overlap(scene, tmp_path):
    dem = geoblock.open_dem(scene / "terrain" / "dem.tif")
    part = render_reference(scene, tmp_path / "part.tif", rows_share=0.5)
    result = match_reference(images(scene), part, dem, reference_accuracy_ce90_m=5.0,
                             dem_sigma_m=5.0)
    full = match_reference(images(scene), scene / "ref_10.tif", dem,
                           reference_accuracy_ce90_m=5.0, dem_sigma_m=5.0)
    assert 0 < len(result) < len(full)
    de, dn, _ = ground_errors(scene, result, "a")
    assert abs(np.median(de) - SHIFT[0]) < 1.5 and abs(np.median(dn) - SHIFT[1]) < 1.5
    far = render_reference(scene, tmp_path / "far.tif", offset_m=(50_000.0, 0.0))
    with pytest.raises(MatchError, match="no image overlaps the reference .*far.tif"):
        match_reference(images(scene), far, dem, reference_accuracy_ce90_m=5.0,
                        dem_sigma_m=5.0)


def test_refusals(scene, tmp_path):
    dem = geoblock.open_dem(scene / "terrain" / "dem.tif")
    with pytest.raises(MatchError, match="reference_accuracy_ce90_m must be a number > 0"):
        match_reference(images(scene), scene / "ref_10.tif", dem,
                        reference_accuracy_ce90_m=0.0, dem_sigma_m=5.0)
    with pytest.raises(MatchError, match="no band 2"):
        match_reference(images(scene), scene / "ref_10.tif", dem,
                        reference_accuracy_ce90_m=5.0, dem_sigma_m=5.0,
                        options=ReferenceOptions(band=2))
    plain = tmp_path / "plain.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(plain, "w", driver="GTiff", width=20, height=20, count=1,
                           dtype="uint8") as dst:
            dst.write(np.ones((20, 20), "uint8"), 1)
    with pytest.raises(MatchError, match="plain.tif: no CRS"):
        match_reference(images(scene), plain, dem, reference_accuracy_ce90_m=5.0,
                        dem_sigma_m=5.0)
    with pytest.raises(MatchError, match="half_px"):
        ReferenceOptions(half_px=1)


def test_fine_image_against_coarse_reference(tmp_path):
    """0.5 m imagery against a 10 m reference: averaged 20 x 20 before the warp."""
    out = tmp_path / "fine"
    run_scenario(scenario_from_dict(scenario(0.5, 2000, 1, 7, 5.0)), out)
    ref = render_reference(out, out / "ref_10.tif")
    result = match_reference(images(out, ("a",)), ref,
                             geoblock.open_dem(out / "terrain" / "dem.tif"),
                             reference_accuracy_ce90_m=5.0, dem_sigma_m=5.0)
    stats = result.image("a")
    assert stats.reduction in (19, 20, 21), stats.summary()
    de, dn, _ = ground_errors(out, result, "a")
    assert de.size >= 20, stats.summary()
    assert abs(np.median(de) - SHIFT[0]) < 1.5 and abs(np.median(dn) - SHIFT[1]) < 1.5


# ------------------------------------------------------------------------------ the CLI
def _run(args):
    from click.testing import CliRunner

    from geoblock.cli.main import build_cli

    return CliRunner().invoke(build_cli(), [str(a) for a in args])


def test_cli_one_image_with_reference(scene, tmp_path):
    from geoblock.io import read_points
    from geoblock.io.points import read_observations

    img, ground = tmp_path / "image.csv", tmp_path / "ground.csv"
    base = ["match", scene / "images" / "a.tif", "--model", scene / "images" / "a_onboard.json",
            "--dem", scene / "terrain" / "dem.tif", "--dem-sigma", "5",
            "--reference", scene / "ref_10.tif", "-o", img]
    result = _run(base)
    assert result.exit_code != 0
    assert "--reference-accuracy" in result.output and "weighs" in result.output
    assert not img.exists() and not ground.exists()
    result = _run(base + ["--reference-accuracy", "5", "--ground-output", ground,
                          "--reference-diagnostics", tmp_path / "cand.csv"])
    assert result.exit_code == 0, result.output
    assert "reference control points in 1 of 1 image(s) from ref_10.tif" in result.stderr
    g, m = read_points(ground), read_points(img)
    assert set(g["source"]) == {"reference:ref_10.tif"} and set(m["kind"]) == {"gcp"}
    assert np.array_equal(g["id"], m["id"]) and set(m["image"]) == {"a"}
    assert np.allclose(g["sigma_shift_e"], 5.0 / CE90_FACTOR)
    local = _run(base[:-1] + [tmp_path / "image2.csv", "--reference-accuracy", "5",
                              "--reference-local-accuracy", "3", "--ground-output",
                              tmp_path / "ground2.csv"])
    assert local.exit_code == 0, local.output
    g2 = read_points(tmp_path / "ground2.csv")
    assert np.allclose(g2["sigma_e"], np.hypot(3.0 / CE90_FACTOR, g["sigma_e"]))
    cand = read_points(tmp_path / "cand.csv")
    assert (cand["status"] == "kept").sum() == g["id"].size
    points, measurements = read_observations(ground, img)
    assert points is not None and len(points.id) == g["id"].size
    # the same run again: the outputs exist and are refused, untouched
    before = ground.read_bytes()
    result = _run(base + ["--reference-accuracy", "5", "--ground-output", ground])
    assert result.exit_code != 0 and "exists" in result.output
    assert ground.read_bytes() == before
    result = _run(["match", scene / "images" / "a.tif", scene / "images" / "b.tif",
                   "--dem", scene / "terrain" / "dem.tif", "--ground-output", ground])
    assert result.exit_code != 0 and "--ground-output applies with --reference" in result.output


def test_cli_block_reference_table(scene, tmp_path):
    from geoblock.io import read_points
    from geoblock.io.blocks import BlockReference, read_block, write_block

    spec = read_block(scene / "block.toml")
    block = tmp_path / "block.toml"
    write_block(block, type(spec)(
        spec.images, spec.method, tmp_path / "points" / "ground.csv",
        tmp_path / "points" / "image.csv", None, spec.dem, spec.options, {}, spec.name,
        spec.mode, BlockReference(scene / "ref_10.tif", 5.0)))
    (tmp_path / "points").mkdir()
    image_csv = tmp_path / "points" / "image.csv"
    # a ground file the user wrote is never replaced without --overwrite
    (tmp_path / "points" / "ground.csv").write_text("id,lon,lat,h\nsurveyed,120.9,23.8,10\n")
    result = _run(["match", block, "-o", image_csv])
    assert result.exit_code != 0 and "ground.csv" in result.output, result.output
    assert "surveyed" in (tmp_path / "points" / "ground.csv").read_text()
    assert not image_csv.exists()
    (tmp_path / "points" / "ground.csv").unlink()
    result = _run(["match", block, "-o", image_csv])
    assert result.exit_code == 0, result.output
    g = read_points(tmp_path / "points" / "ground.csv")
    m = read_points(image_csv)
    assert set(m["kind"]) == {"tp", "gcp"}
    gcp = m["kind"] == "gcp"
    assert set(m["id"][gcp]) == set(g["id"]) and set(m["image"][gcp]) == {"a", "b"}
    assert np.allclose(g["sigma_shift_e"], 5.0 / CE90_FACTOR)
    assert "tie points" in result.stderr and "reference control points" in result.stderr
