"""``geoblock ortho --accuracy-layer`` and its carry-through by ``geoblock mosaic`` (issue 28,
item 3), on the Ventoux Pleiades crop with its RPC under an RPCV-1 correction."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

from geoblock.io import open_model, write_model
from geoblock.models import ImageCorrection
from geoblock.models.uncertainty import ModelPosterior

SRTM = "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"
RPC = "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"
IMAGE = "shareloc/image/phr_ventoux/left_image.tif"


@pytest.fixture
def scene(tmp_path, data_dir):
    """(image, model JSON with a posterior, model JSON without any accuracy, DEM args)."""
    model = ImageCorrection(open_model(data_dir / RPC), 1)
    cov = np.diag([0.3, 1e-3, 1e-3, 0.4, 1e-3, 1e-3]) ** 2
    post = ModelPosterior(model.parameters.names, cov, 0.9, 40, "geoblock adjust t.toml")
    with_post = str(write_model(model, tmp_path / "adjusted.json", posterior=post))
    bare = str(write_model(model, tmp_path / "bare.json"))
    dem = ["--dem", str(data_dir / SRTM), "--geoid", str(data_dir / GEOID), "--no-progress"]
    return str(data_dir / IMAGE), with_post, bare, dem


def _read(path):
    with rasterio.open(path) as ds:
        return ds.read(), ds.profile, ds.tags(), ds.descriptions, ds.units


def test_ortho_writes_the_layer_beside_it(runner, cli, tmp_path, scene):
    image, model, _, dem = scene
    out = tmp_path / "o.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), *dem, "--model", model,
                                 "--dem-sigma", "5", "--accuracy-layer", "--chunks", "256"])
    assert result.exit_code == 0, result.output
    layer = tmp_path / "o_accuracy.tif"
    values, profile, tags, desc, units = _read(layer)
    ortho, oprofile, *_ = _read(out)
    # the ortho's grid, CRS, block size; float32 metres, nodata exactly where the ortho's
    for key in ("crs", "transform", "width", "height", "blockxsize", "blockysize"):
        assert profile[key] == oprofile[key]
    assert profile["dtype"] == "float32" and np.isnan(profile["nodata"])
    np.testing.assert_array_equal(np.isfinite(values[0]), ortho[0] != oprofile["nodata"])
    assert desc == ("predicted horizontal error (m, radial RMS)",) and units == ("m",)
    assert tags["GEOBLOCK_ACCURACY"].startswith("predicted horizontal error (m)")
    assert tags["GEOBLOCK_ACCURACY_COVARIANCE"] == "posterior"
    assert tags["GEOBLOCK_ACCURACY_SOURCE"].startswith("geoblock adjust t.toml")
    assert tags["GEOBLOCK_ACCURACY_DEM_SIGMA"] == "5"
    assert tags["GEOBLOCK_ACCURACY_MODEL"] == "crop of image-correction of rpc"
    # 0.3/0.4 px of 0.5 m and 5 m of DEM error at 8.6 deg incidence
    assert 0.7 < float(np.nanmin(values)) <= float(np.nanmax(values)) < 0.95
    assert "o_accuracy.tif: accuracy layer (posterior" in result.output


def test_same_bytes_on_every_scheduler(runner, cli, tmp_path, scene):
    image, model, _, dem = scene
    files = {}
    for scheduler in ("threads", "synchronous", "processes"):
        layer = tmp_path / f"{scheduler}_acc.tif"
        result = runner.invoke(cli, ["ortho", image, str(tmp_path / f"{scheduler}.tif"), *dem,
                                     "--model", model, "--dem-sigma", "3", "--chunks", "200",
                                     "--scheduler", scheduler, "--accuracy-layer", str(layer)])
        assert result.exit_code == 0, result.output
        files[scheduler] = _read(layer)[0]
    np.testing.assert_array_equal(files["threads"], files["synchronous"])
    np.testing.assert_array_equal(files["threads"], files["processes"])


def test_refusals(runner, cli, tmp_path, scene):
    image, model, bare, dem = scene
    out = str(tmp_path / "o.tif")
    result = runner.invoke(cli, ["ortho", image, out, *dem, "--model", model,
                                 "--accuracy-layer"])
    assert result.exit_code == 2 and "--dem-sigma" in result.output
    result = runner.invoke(cli, ["ortho", image, out, *dem, "--model", model,
                                 "--dem-sigma", "4"])
    assert result.exit_code == 2 and "only with --accuracy-layer" in result.output
    result = runner.invoke(cli, ["ortho", image, out, *dem, "--model", bare,
                                 "--dem-sigma", "4", "--accuracy-layer"])
    assert result.exit_code == 1 and "states no accuracy" in result.output
    assert "geoblock adjust" in result.output
    (tmp_path / "o_accuracy.tif").write_bytes(b"mine")
    result = runner.invoke(cli, ["ortho", image, out, *dem, "--model", model,
                                 "--dem-sigma", "4", "--accuracy-layer"])
    assert result.exit_code == 1 and "o_accuracy.tif" in result.output
    assert (tmp_path / "o_accuracy.tif").read_bytes() == b"mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adjusted.json", "bare.json",
                                                          "o_accuracy.tif"]


def _two_orthos(runner, cli, tmp_path, scene, layers=(True, True)):
    image, model, _, dem = scene
    bounds = [("675200", "4897050", "675450", "4897300"), ("675350", "4897100", "675600",
                                                             "4897350")]
    paths = []
    for k, (b, layer) in enumerate(zip(bounds, layers, strict=True)):
        out = tmp_path / f"o{k}.tif"
        args = ["ortho", image, str(out), *dem, "--model", model, "--crs", "EPSG:32631",
                "--res", "0.5", "--bounds", *b]
        if layer:
            args += ["--dem-sigma", str(3 + 3 * k), "--accuracy-layer"]
        result = runner.invoke(cli, args)
        assert result.exit_code == 0, result.output
        paths.append(str(out))
    return paths


@pytest.mark.parametrize("method", ["priority", "feather"])
def test_mosaic_carries_the_layers_through(runner, cli, tmp_path, scene, method):
    orthos = _two_orthos(runner, cli, tmp_path, scene)
    out = tmp_path / "m.tif"
    result = runner.invoke(cli, ["mosaic", str(out), *orthos, "--method", method,
                                 "--contribution", str(tmp_path / "c.tif"), "--no-progress"])
    assert result.exit_code == 0, result.output
    acc, profile, tags, desc, _ = _read(tmp_path / "m_accuracy.tif")
    mos, mprofile, *_ = _read(out)
    contrib = _read(tmp_path / "c.tif")[0][0]
    assert profile["transform"] == mprofile["transform"] and profile["crs"] == mprofile["crs"]
    np.testing.assert_array_equal(np.isfinite(acc[0]), contrib > 0)
    assert tags["GEOBLOCK_ACCURACY_MOSAIC"].startswith(method)
    a = [_read(p.replace(".tif", "_accuracy.tif"))[0][0] for p in orthos]
    # the sources' layers on the mosaic grid (o0 at the top left, o1 shifted)
    t0 = mprofile["transform"]
    placed = []
    for p, layer in zip(orthos, a, strict=True):
        with rasterio.open(p) as ds:
            r0 = round((ds.transform.f - t0.f) / t0.e)
            c0 = round((ds.transform.c - t0.c) / t0.a)
        full = np.full(acc[0].shape, np.nan, np.float32)
        full[r0:r0 + layer.shape[0], c0:c0 + layer.shape[1]] = layer
        placed.append(full)
    one = contrib == 1
    only1 = one & ~np.isfinite(placed[1])
    np.testing.assert_array_equal(acc[0][only1], placed[0][only1])
    both = np.isfinite(placed[0]) & np.isfinite(placed[1])
    assert both.sum() > 1000
    if method == "priority":
        np.testing.assert_array_equal(acc[0][both], placed[0][both])
    else:  # between the two sources' errors (weights' average), strictly inside somewhere
        lo = np.minimum(placed[0], placed[1])[both]
        hi = np.maximum(placed[0], placed[1])[both]
        got = acc[0][both]
        assert np.all((got >= lo * (1 - 1e-6)) & (got <= hi * (1 + 1e-6)))
        assert np.any((got > lo * 1.01) & (got < hi * 0.99))


def test_mosaic_without_every_layer(runner, cli, tmp_path, scene):
    orthos = _two_orthos(runner, cli, tmp_path, scene, layers=(True, False))
    out = tmp_path / "m.tif"
    result = runner.invoke(cli, ["mosaic", str(out), *orthos, "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "no accuracy layer for the mosaic" in result.output and "o1.tif" in result.output
    assert not (tmp_path / "m_accuracy.tif").exists()
    result = runner.invoke(cli, ["mosaic", str(out), *orthos, "--no-progress", "--overwrite",
                                 "--accuracy-layer"])
    assert result.exit_code == 1 and "no accuracy layer for ORTHO" in result.output
    result = runner.invoke(cli, ["mosaic", str(out), *orthos, "--no-progress", "--overwrite",
                                 "--source-accuracy", orthos[0].replace(".tif",
                                                                        "_accuracy.tif")])
    assert result.exit_code == 2 and "one per ORTHO" in result.output
