"""Issue 12, item 1: vendor crops. ``geoblock ortho`` (and ``localize``) on a crop of a scene
with the full scene's model.

Data: shareloc's Ventoux crop ``image/phr_ventoux/left_image.tif`` (500 x 500 px, no CRS, a
pixel-unit geotransform saying it starts at row/col 5000 of the 41801 x 39182 scene) and the
scene's RPC (``rpc/phr_ventoux/left_image.geom`` and the DIMAP ``RPC_*.XML``).

Before the fix the ortho exited 0 after two minutes with a whole-scene output and the crop's
pixels at the scene's top-left (~2.5 km off). Now the crop offset of the geotransform is
applied; an image stating no offset whose shape differs from the model's is refused with what
to pass (``--crop-offset ROW COL`` / ``--no-crop``).

The placement check orthorectifies a *coordinate image*: the crop's geotransform, two float64
bands holding each pixel's own (row, col). Bilinear resampling reproduces a linear function
exactly, so each output pixel holds the crop position the ortho sampled; it must be where the
full-scene model puts the pixel's ground point, minus 5000 (0.05 px).
"""

from __future__ import annotations

import warnings

import numpy as np
import pyproj
import pytest
import rasterio
from rasterio.errors import NotGeoreferencedWarning

import geoblock

CROP = "shareloc/image/phr_ventoux/left_image.tif"
GEOM = "shareloc/rpc/phr_ventoux/left_image.geom"
DIMAP = "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"
OFFSET = 5000.0
DEM = "const:300"


def _write(path, data, transform=None):
    bands, rows, cols = data.shape
    profile = {"driver": "GTiff", "width": cols, "height": rows, "count": bands,
               "dtype": data.dtype.name}
    if transform is not None:
        profile["transform"] = transform
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path, "w", **profile) as ds:
            ds.write(data)
    return str(path)


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path) as ds:
            return ds.read(), ds.transform, ds.crs


@pytest.fixture(scope="module")
def crop(data_dir):
    path = data_dir / CROP
    if not path.exists():
        pytest.skip(f"{path} not found")
    pixels, transform, crs = _read(path)
    assert pixels.shape == (1, 500, 500) and crs is None
    assert tuple(transform)[:6] == (1.0, 0.0, OFFSET, 0.0, 1.0, OFFSET)
    return str(path), pixels


def _ortho(runner, cli, image, out, model, *args):
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", DEM, "--model", str(model),
                                 "--no-progress", "--scheduler", "synchronous", *args])
    return result


def _centres(transform, crs, shape):
    """lon, lat of the output pixel centres, (rows, cols) each."""
    rows, cols = shape
    x = transform.c + transform.a * (np.arange(cols) + 0.5)
    y = transform.f + transform.e * (np.arange(rows) + 0.5)
    xx, yy = np.meshgrid(x, y)
    to_geo = pyproj.Transformer.from_crs(crs.to_wkt(), "EPSG:4326", always_xy=True)
    return to_geo.transform(xx, yy)


@pytest.mark.parametrize("metadata", [GEOM, DIMAP], ids=["geom", "dimap"])
def test_every_pixel_lands_where_the_full_scene_model_puts_it(runner, cli, tmp_path, data_dir,
                                                              crop, metadata):
    """The must-show: the crop's ortho samples the crop at full-model position - 5000."""
    full = geoblock.open_model(data_dir / metadata)
    assert full.shape[0] > 40000 and full.shape[1] > 39000  # the whole scene's model
    rows, cols = np.mgrid[0:500, 0:500].astype(np.float64)
    coords = _write(tmp_path / "coords.tif", np.stack([rows, cols]),
                    transform=rasterio.Affine(1, 0, OFFSET, 0, 1, OFFSET))
    out = tmp_path / "coords_ortho.tif"
    result = _ortho(runner, cli, coords, out, data_dir / metadata, "--res", "1",
                    "--chunks", "128")
    assert result.exit_code == 0, result.output
    assert "crop at row/col 5000, 5000" in result.output
    sampled, transform, crs = _read(out)
    # the output covers the crop (~250 m at 0.5 m GSD), not the 20 km scene
    assert max(sampled.shape[1:]) < 400, sampled.shape
    lon, lat = _centres(transform, crs, sampled.shape[1:])
    h = geoblock.open_dem(DEM).height(lon, lat)
    row, col = full.project(lon, lat, h)
    valid = np.isfinite(sampled).all(axis=0)
    assert valid.mean() > 0.5  # most of the grid sees the crop
    inside = (row - OFFSET > 1) & (row - OFFSET < 498) & (col - OFFSET > 1) & (col - OFFSET < 498)
    assert np.array_equal(valid & inside, inside)  # every pixel inside the crop was sampled
    err = np.hypot(sampled[0] - (row - OFFSET), sampled[1] - (col - OFFSET))[valid]
    assert err.max() < 0.05, err.max()


def test_the_real_crop_is_placed_and_fast(runner, cli, tmp_path, data_dir, crop):
    """``geoblock ortho left_image.tif --model <scene RPC>``: a crop-sized output whose
    values are the crop's, sampled at the full-scene model's positions - 5000."""
    image, pixels = crop
    out = tmp_path / "ortho.tif"
    result = _ortho(runner, cli, image, out, data_dir / GEOM)
    assert result.exit_code == 0, result.output
    values, transform, crs = _read(out)
    assert max(values.shape[1:]) < 600, values.shape  # not the 41801 x 39182 scene
    lon, lat = _centres(transform, crs, values.shape[1:])
    full = geoblock.open_model(data_dir / GEOM)
    row, col = full.project(lon, lat, 300.0)
    row, col = row - OFFSET, col - OFFSET
    pick = (row > 1) & (row < 497) & (col > 1) & (col < 497)
    assert pick.sum() > 1000
    r, c = row[pick], col[pick]
    r0, c0 = np.floor(r).astype(int), np.floor(c).astype(int)
    fr, fc = r - r0, c - c0
    img = pixels[0].astype(float)
    expected = ((1 - fr) * (1 - fc) * img[r0, c0] + (1 - fr) * fc * img[r0, c0 + 1]
                + fr * (1 - fc) * img[r0 + 1, c0] + fr * fc * img[r0 + 1, c0 + 1])
    assert np.abs(values[0][pick] - expected).max() <= 1.01  # uint16 rounding


def test_the_crops_own_model_is_not_shifted_twice(runner, cli, tmp_path, data_dir, crop):
    """An RPC read with crop_from_geotransform=True has the crop's shape: used as it is."""
    image, _ = crop
    own = geoblock.open_model(data_dir / GEOM, image=image, crop_from_geotransform=True)
    assert own.shape == (500, 500)
    own_path = geoblock.write_model(own, tmp_path / "own.json")
    grid = ["--crs", "EPSG:32631", "--res", "2"]
    a, b = tmp_path / "a.tif", tmp_path / "b.tif"
    assert _ortho(runner, cli, image, a, data_dir / GEOM, *grid).exit_code == 0
    result = _ortho(runner, cli, image, b, own_path, *grid)
    assert result.exit_code == 0, result.output
    assert "crop at" not in result.output
    va, ta, _ = _read(a)
    vb, tb, _ = _read(b)
    assert ta == tb and va.shape == vb.shape
    assert np.abs(va.astype(int) - vb.astype(int)).max() <= 1


def test_a_crop_stating_no_offset_is_refused_then_placed_by_crop_offset(runner, cli, tmp_path,
                                                                        data_dir, crop):
    _, pixels = crop
    raw = _write(tmp_path / "raw.tif", pixels)  # the same pixels, no geotransform
    out = tmp_path / "o.tif"
    result = _ortho(runner, cli, raw, out, data_dir / GEOM)
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert len(errors) == 1, result.output
    for words in ("raw.tif", "500 x 500", "41801 x 39182", "--crop-offset ROW COL",
                  "--no-crop"):
        assert words in errors[0], errors[0]
    assert not out.exists()

    grid = ["--crs", "EPSG:32631", "--res", "2"]
    stated, given = tmp_path / "stated.tif", tmp_path / "given.tif"
    assert _ortho(runner, cli, crop[0], stated, data_dir / GEOM, *grid).exit_code == 0
    result = _ortho(runner, cli, raw, given, data_dir / GEOM, "--crop-offset", "5000", "5000",
                    *grid)
    assert result.exit_code == 0, result.output
    assert "(--crop-offset)" in result.output
    v1, t1, _ = _read(stated)
    v2, t2, _ = _read(given)
    assert t1 == t2 and np.array_equal(v1, v2)


@pytest.mark.parametrize(("args", "code", "words"), [
    (["--crop-offset", "5000", "5000", "--no-crop"], 2, "not both"),
    (["--crop-offset", "nan", "0"], 2, "--crop-offset"),
    (["--crop-offset", "41500", "0"], 1, "does not lie inside"),
])
def test_bad_crop_options(runner, cli, tmp_path, data_dir, crop, args, code, words):
    out = tmp_path / "o.tif"
    result = _ortho(runner, cli, crop[0], out, data_dir / GEOM, *args)
    assert result.exit_code == code, result.output
    assert words in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_localize_points_of_the_crop(runner, cli, tmp_path, data_dir, crop):
    """``geoblock localize --image``: crop pixels are scene pixels + 5000."""
    points = tmp_path / "points.csv"
    points.write_text("id,row,col\na,0,0\nb,499,250.5\n", encoding="utf-8")
    full = geoblock.open_model(data_dir / GEOM)
    expected = full.backproject(np.array([0.0, 499.0]) + OFFSET,
                                np.array([0.0, 250.5]) + OFFSET, 300.0)

    def run(*args):
        out = tmp_path / "ground.csv"
        result = runner.invoke(cli, ["localize", str(data_dir / GEOM), str(points), "--dem",
                                     DEM, "-o", str(out), "--overwrite", *args])
        return result, out

    for args in (["--image", crop[0]], ["--crop-offset", "5000", "5000"]):
        result, out = run(*args)
        assert result.exit_code == 0, result.output
        table = geoblock.io.read_points(out)
        assert np.allclose(table["lon"], expected.lon, rtol=0, atol=1e-9)
        assert np.allclose(table["lat"], expected.lat, rtol=0, atol=1e-9)
    raw = _write(tmp_path / "raw.tif", crop[1])
    result, out = run("--image", raw)
    assert result.exit_code == 1 and "--crop-offset ROW COL" in result.output, result.output
