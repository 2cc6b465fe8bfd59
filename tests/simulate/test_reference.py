"""Reference orthos rendered from the ground truth (geoblock.simulate.reference): a pixel shows
the texture where its centre is, minus the stated shift; the GeoTIFF's corner transform puts
pixel centres half a pixel in; pixels are area averages; the shift is metres of local east and
north."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
import rasterio
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock import coords
from geoblock.errors import GeoblockError
from geoblock.simulate.reference import (
    default_supersample,
    render_reference,
    shift_lonlat,
)
from geoblock.simulate.render import ProceduralTexture
from geoblock.simulate.terrain import Grid, ridged_terrain

LON0, LAT0 = 120.95, 23.85
CRS = coords.utm_crs(LON0, LAT0)  # EPSG:32651
X0, Y0 = (round(v, -1) for v in coords.transformer("EPSG:4326", CRS).transform(LON0, LAT0))


@dataclass(frozen=True)
class Ramp:
    """A texture linear in longitude and latitude: its area average over a symmetric set of
    samples is its value at the centre, so a pixel's value names the point it shows."""

    def __call__(self, lon, lat):
        return 0.5 + 20.0 * (np.asarray(lon) - LON0) + 30.0 * (np.asarray(lat) - LAT0)


@dataclass(frozen=True)
class Disc:
    """A bright disc of ``radius_m`` around a ground point: its centroid on the reference is
    where the reference shows the point."""

    lon: float
    lat: float
    radius_m: float

    def __call__(self, lon, lat):
        de, dn, _ = coords.enu_offsets(self.lon, self.lat, 0.0, lon, lat, 0.0)
        return np.where(np.hypot(de, dn) < self.radius_m, 1.0, 0.0)


BOUNDS = (X0 - 300.0, Y0 - 200.0, X0 + 300.0, Y0 + 200.0)


def test_a_pixel_shows_the_texture_at_its_centre_minus_the_shift():
    ramp = Ramp()
    shift = (3.7, -4.2)
    ref = render_reference(ramp, BOUNDS, 10.0, CRS, shift_en_m=shift, dtype="float32")
    rows, cols = ref.pixels.shape
    assert (rows, cols) == (40, 60)
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    lon, lat = ref.pixel_lonlat(r, c)  # where the reference says the centre is
    true_lon, true_lat = shift_lonlat(lon, lat, -shift[0], -shift[1])
    np.testing.assert_allclose(ref.pixels, ramp(true_lon, true_lat), atol=2e-6)
    # the same through the object's own helper
    tl, tt = ref.true_lonlat(lon, lat)
    np.testing.assert_allclose(tl, true_lon, rtol=0, atol=1e-12)
    # without the shift the values differ by the ramp's change over 3.7 m E, 4.2 m S
    assert np.abs(ref.pixels - ramp(lon, lat)).min() > 1e-5


def test_the_geotiff_transform_maps_corners_and_centres_are_half_a_pixel_in(tmp_path):
    ramp = Ramp()
    ref = render_reference(ramp, BOUNDS, 10.0, CRS, shift_en_m=(0.0, 0.0), dtype="float32",
                           path=tmp_path / "ref.tif")
    with rasterio.open(ref.path) as ds:
        t = ds.transform
        assert (t.a, t.e) == (10.0, -10.0)
        # edges snapped to whole pixels, outwards
        assert (t.c, t.f) == (BOUNDS[0], BOUNDS[3])
        assert pyproj_equal(ds.crs.to_wkt(), CRS)
        data = ds.read(1)
        assert ds.tags()["GEOBLOCK_REFERENCE_GSD_M"] == "10.0"
        # rasterio's xy() gives pixel centres: the pixel's value is the ramp there
        for r, c in ((0, 0), (7, 13), (39, 59)):
            x, y = ds.xy(r, c)
            assert (x, y) == (t.c + 10.0 * (c + 0.5), t.f - 10.0 * (r + 0.5))
            lon, lat = coords.transformer(CRS, "EPSG:4326").transform(x, y)
            assert data[r, c] == pytest.approx(float(ramp(lon, lat)), abs=2e-6)
        # a ground point half a pixel right and down of a corner is a pixel centre
        x, y = t.c + 10.0 * 5.5, t.f - 10.0 * 2.5
        assert ds.index(x, y) == (2, 5)
    lon, lat = coords.transformer(CRS, "EPSG:4326").transform(x, y)
    row, col = ref.lonlat_pixel(lon, lat)
    assert (row, col) == (pytest.approx(2.0, abs=1e-6), pytest.approx(5.0, abs=1e-6))


def pyproj_equal(wkt, crs):
    import pyproj

    return pyproj.CRS.from_wkt(wkt).equals(crs)


@pytest.mark.parametrize("shift", [(4.0, 0.0), (0.0, -3.0), (-2.5, 4.5)])
def test_a_feature_appears_displaced_by_the_shift(shift):
    """A 30 m disc at a known ground point: its centroid on the 2.5 m reference is the point
    plus the shift (metres of local east and north), within a twentieth of a pixel."""
    disc = Disc(LON0, LAT0, 30.0)
    ref = render_reference(disc, BOUNDS, 2.5, CRS, shift_en_m=shift, dtype="float32",
                           supersample=6)
    w = ref.pixels.astype(float)
    r, c = np.meshgrid(np.arange(w.shape[0]), np.arange(w.shape[1]), indexing="ij")
    lon, lat = ref.pixel_lonlat((w * r).sum() / w.sum(), (w * c).sum() / w.sum())
    de, dn, _ = coords.enu_offsets(LON0, LAT0, 0.0, lon, lat, 0.0)
    assert de == pytest.approx(shift[0], abs=0.12)
    assert dn == pytest.approx(shift[1], abs=0.12)
    # and displaced_lonlat says where that is
    lon2, lat2 = ref.displaced_lonlat(LON0, LAT0)
    de2, dn2, _ = coords.enu_offsets(LON0, LAT0, 0.0, lon2, lat2, 0.0)
    assert (float(de2), float(dn2)) == (pytest.approx(shift[0], abs=1e-6),
                                        pytest.approx(shift[1], abs=1e-6))


def test_pixels_are_area_averages():
    """A 2 m checkerboard under 10 m pixels: supersampled, every pixel is near the mean;
    sampled at the centre only (supersample=1), pixels take the checkerboard's values."""

    def checker(lon, lat):
        x, y = coords.transformer("EPSG:4326", CRS).transform(lon, lat)
        return ((np.floor(np.asarray(x) / 2.0) + np.floor(np.asarray(y) / 2.0)) % 2).astype(float)

    averaged = render_reference(checker, BOUNDS, 10.0, CRS, dtype="float32", supersample=5)
    centre = render_reference(checker, BOUNDS, 10.0, CRS, dtype="float32", supersample=1)
    assert averaged.supersample == 5 and centre.supersample == 1
    assert abs(float(averaged.pixels.mean()) - 0.5) < 0.05
    assert float(np.abs(averaged.pixels - 0.5).max()) < 0.25
    assert set(np.unique(centre.pixels).tolist()) <= {0.0, 1.0}
    assert default_supersample(2.5) == 2 and default_supersample(10.0) == 3
    assert default_supersample(20.0) == 6 and default_supersample(100.0) == 8


def test_sub_samples_are_where_a_projection_of_each_would_put_them():
    """The sub-samples are placed from the pixel centres through local derivatives: the same
    values as projecting every sub-sample (a procedural texture, 3 x 3 per pixel, shifted)."""
    texture = ProceduralTexture((LON0, LAT0), seed=5)
    ref = render_reference(texture, BOUNDS, 10.0, CRS, shift_en_m=(2.0, -1.0),
                           dtype="float32", supersample=3)
    t = ref.transform
    rows, cols = ref.pixels.shape
    off = (np.arange(3) + 0.5) / 3
    ys = t.f + t.e * (np.arange(rows)[:, None] + off).ravel()
    xs = t.c + t.a * (np.arange(cols)[:, None] + off).ravel()
    xx, yy = np.meshgrid(xs, ys)
    lon, lat = coords.transformer(CRS, "EPSG:4326").transform(xx, yy)
    lon, lat = shift_lonlat(lon, lat, -2.0, 1.0)
    brute = np.clip(texture(lon, lat), 0, 1).reshape(rows, 3, cols, 3).mean(axis=(1, 3))
    np.testing.assert_allclose(ref.pixels, brute, atol=1e-6)


def test_integer_pixels_and_shading():
    texture = ProceduralTexture((LON0, LAT0), seed=3)
    grid = Grid.from_bounds((BOUNDS[0] - 500, BOUNDS[1] - 500, BOUNDS[2] + 500, BOUNDS[3] + 500),
                            20.0, CRS)
    terrain = ridged_terrain(grid, (100.0, 900.0), seed=1)
    flat = render_reference(texture, BOUNDS, 10.0, CRS)
    shaded = render_reference(texture, BOUNDS, 10.0, CRS, terrain=terrain, noise_dn=1.0)
    assert flat.pixels.dtype == np.uint8 and flat.pixels.min() >= 1
    assert shaded.pixels.min() >= 1
    assert np.abs(shaded.pixels.astype(int) - flat.pixels.astype(int)).mean() > 3.0
    wide = render_reference(texture, BOUNDS, 10.0, CRS, dtype="uint16")
    assert wide.pixels.dtype == np.uint16 and wide.pixels.max() > 255


def test_edges_snap_outwards_to_whole_pixels():
    ref = render_reference(Ramp(), (BOUNDS[0] + 3.0, BOUNDS[1] + 3.0, BOUNDS[2] - 3.0,
                                    BOUNDS[3] + 0.5), 10.0, CRS, dtype="float32")
    assert ref.grid.bounds == (BOUNDS[0], BOUNDS[1], BOUNDS[2], BOUNDS[3] + 10.0)


def test_a_geographic_reference():
    ramp = Ramp()
    d = 0.004
    ref = render_reference(ramp, (LON0 - d, LAT0 - d, LON0 + d, LAT0 + d), 10.0, "EPSG:4326",
                           shift_en_m=(5.0, 5.0), dtype="float32")
    assert ref.grid.is_geographic
    assert ref.gsd_m == pytest.approx(10.0)
    r, c = np.meshgrid(np.arange(ref.pixels.shape[0]), np.arange(ref.pixels.shape[1]),
                       indexing="ij")
    lon, lat = ref.true_lonlat(*ref.pixel_lonlat(r, c))
    np.testing.assert_allclose(ref.pixels, ramp(lon, lat), atol=2e-6)


@pytest.mark.parametrize("kwargs, message", [
    ({"gsd_m": 0.0}, "gsd_m"),
    ({"gsd_m": float("nan")}, "gsd_m"),
    ({"bounds": (10.0, 0.0, 0.0, 10.0)}, "east > west"),
    ({"shift_en_m": (float("inf"), 0.0)}, "shift_en_m"),
    ({"dtype": "int8"}, "dtype"),
    ({"supersample": 0}, "supersample"),
    ({"supersample": 2.5}, "supersample"),
    ({"noise_dn": -1.0}, "noise_dn"),
])
def test_bad_arguments_are_refused(kwargs, message):
    args = {"bounds": BOUNDS, "gsd_m": 10.0}
    args.update({k: v for k, v in kwargs.items() if k in args})
    options = {k: v for k, v in kwargs.items() if k not in args}
    with pytest.raises(GeoblockError, match=message):
        render_reference(Ramp(), args["bounds"], args["gsd_m"], CRS, **options)


@settings(max_examples=50, deadline=None)
@given(st.floats(-60.0, 60.0), st.floats(-179.0, 179.0), st.floats(-50.0, 50.0),
       st.floats(-50.0, 50.0))
def test_shift_lonlat_moves_by_metres_of_local_east_and_north(lat, lon, de, dn):
    lon2, lat2 = shift_lonlat(lon, lat, de, dn)
    e, n, _ = coords.enu_offsets(lon, lat, 0.0, lon2, lat2, 0.0)
    assert float(e) == pytest.approx(de, abs=1e-3)
    assert float(n) == pytest.approx(dn, abs=1e-3)
    back = shift_lonlat(lon2, lat2, -de, -dn)
    # within 1 mm (radii taken at each end), in metres: a degree of longitude shrinks with
    # the latitude (1e-8 degrees of it is 0.57 mm at 59 N, the case hypothesis found)
    e_back, n_back, _ = coords.enu_offsets(lon, lat, 0.0, back[0], back[1], 0.0)
    assert math.hypot(float(e_back), float(n_back)) < 1e-3
