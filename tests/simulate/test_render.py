"""Rendered raw images: a flat constant scene is constant, pixels show the texture where the
true model sees it, the lattice stays within its measured error, and the files written open
with rasterio, geoblock.io and ``geoblock ortho``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import rasterio
from rasterio.errors import NotGeoreferencedWarning

from geoblock.dem import localize
from geoblock.errors import GeoblockError
from geoblock.io import open_image, open_model
from geoblock.simulate.render import (
    ConstantTexture,
    ProceduralTexture,
    pixel_ground,
    render,
    render_image,
)
from geoblock.simulate.terrain import Grid, ridged_terrain
from geoblock.testing.synthetic import ConstantVelocityPushbroom

SHAPE = (120, 150)


def oblique(shape=SHAPE, roll_deg=15.0):
    """A 2.5 m pushbroom looking ``roll_deg`` across track (Teo et al.'s strip 3: 14.8)."""
    rows = shape[0]
    return ConstantVelocityPushbroom(
        shape, origin=(7.05, 43.70), position=(0.0, -2.5 * rows / 2, 700e3),
        velocity=(0.0, 7000.0, 0.0), line_period=2.5 / 7000.0, ifov=2.5 / 700e3,
        attitude=(np.radians(roll_deg), 0.0, 0.0))


@pytest.fixture(scope="module")
def scene():
    model = oblique()
    fp = model.footprint(h=0.0)
    grid = Grid.around(float(fp.lon.mean()), float(fp.lat.mean()), 1500.0, 10.0)
    return model, ridged_terrain(grid, (0.0, 800.0), max_slope_deg=60.0, seed=2)


def test_flat_constant_scene_renders_constant():
    model = oblique()
    img = render_image(model, 250.0, texture=ConstantTexture(0.5))
    assert img.pixels.dtype == np.uint8 and img.pixels.shape == SHAPE
    assert (img.pixels == 128).all()  # 1 + 0.5 * 254 = 128: flat ground is not shaded
    img16 = render_image(model, 250.0, texture=ConstantTexture(1.0), hillshade=False,
                         dtype="uint16")
    assert (img16.pixels == 65535).all()


def test_pixels_show_the_texture_where_the_true_model_sees_it(scene):
    """Each pixel's value is the texture at the exact intersection of its line of sight."""
    model, terrain = scene
    texture = ProceduralTexture((7.05, 43.70), seed=4, field_size_m=60.0)
    img = render_image(model, terrain, texture=texture, hillshade=False)
    rng = np.random.default_rng(0)
    r, c = rng.integers(0, SHAPE[0], 300), rng.integers(0, SHAPE[1], 300)
    ground, status = localize(model, r.astype(float), c.astype(float), terrain.to_dem())
    assert (status == 0).all()
    expected = np.clip(np.round(1 + texture(ground.lon, ground.lat) * 254), 1, 255)
    # the lattice moves ground points by < 0.1 px: crop rows (6-20 m period, +-15 DN) change
    # by a few DN, a value jumps only where a sharp edge (road, hedge, river) passes
    diff = np.abs(img.pixels[r, c] - expected)
    assert np.mean(diff <= 3) > 0.97, np.sort(diff)[-20:]


def test_lattice_error_is_measured_and_small(scene):
    model, terrain = scene
    dem = terrain.to_dem()
    lon1, lat1, ok1, _ = pixel_ground(model, dem, 0, 40, lattice_step=1)
    lon8, lat8, ok8, stats = pixel_ground(model, dem, 0, 40, lattice_step=8, tolerance_px=0.05)
    assert ok1.all() and ok8.all()
    err_px = np.hypot((lon8 - lon1) * np.cos(np.radians(lat1)), lat8 - lat1) * 111319.5 / 2.5
    # measured on this 0-800 m, 60 degree terrain seen 15 degrees off nadir
    assert err_px.max() < 0.15
    assert stats["max_error_px"] <= 0.05 and stats["exact"] < 0.3 * stats["pixels"]


def test_hillshade_makes_relief_visible(scene):
    model, terrain = scene
    img = render_image(model, terrain, texture=ConstantTexture(0.6))
    assert img.pixels.std() > 10  # the shading alone varies on rugged terrain
    assert 0 < img.exact_fraction < 0.5 and img.lattice_error_px <= 0.05


def test_deterministic_and_noise(scene):
    model, terrain = scene
    a = render_image(model, terrain, seed=1)
    b = render_image(model, terrain, seed=1)
    np.testing.assert_array_equal(a.pixels, b.pixels)
    noisy = render_image(model, terrain, seed=1, noise_dn=3.0)
    d = noisy.pixels.astype(float) - a.pixels
    assert 2.0 < d[(a.pixels > 10) & (a.pixels < 245)].std() < 4.0


def test_no_terrain_is_nodata():
    model = oblique((20, 30))
    grid = Grid.around(7.05, 43.70, 500.0, 10.0)  # far from the footprint
    terrain = ridged_terrain(grid, (0.0, 100.0))
    img = render_image(model, terrain)
    assert (img.pixels == 0).all()


def test_written_image_opens_and_orthorectifies(tmp_path, scene):
    model, terrain = scene
    dem_path = terrain.write(tmp_path / "dem.tif")
    image_path, model_path, rendered = render(model, terrain, tmp_path / "scene.tif")
    assert model_path == tmp_path / "scene.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(image_path) as ds:
            assert ds.crs is None and ds.nodata == 0 and ds.dtypes[0] == "uint8"
            np.testing.assert_array_equal(ds.read(1), rendered.pixels)
    src = open_image(image_path)
    assert src.shape == SHAPE and src.bands == 1
    assert open_model(model_path) == model
    from click.testing import CliRunner

    from geoblock.cli.main import cli

    out = tmp_path / "ortho.tif"
    result = CliRunner().invoke(cli, ["ortho", str(image_path), str(out), "--model",
                                      str(model_path), "--dem", str(dem_path)])
    assert result.exit_code == 0, result.output
    with rasterio.open(out) as ds:
        ortho = ds.read(1)
        assert ds.crs is not None and (ortho > 0).mean() > 0.3


def test_bad_arguments(scene):
    model, terrain = scene
    with pytest.raises(GeoblockError, match="dtype"):
        render_image(model, terrain, dtype="float32")
    with pytest.raises(GeoblockError, match="lattice_step"):
        pixel_ground(model, terrain.to_dem(), lattice_step=0)
