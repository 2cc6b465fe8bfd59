"""The compiled scan of approximate rays (geoblock.dem._raycast) against the exact numpy scan.

``localize(method="robust")`` scans approximate rays first when the DEM is a lon/lat raster
(:meth:`RasterDem._ray_window`), and the exact rays only where that scan is not sure. These
tests run both paths (``intersect._FAST_SCAN``) on the same rays and ask for the same statuses
and the same first crossing, on the steep profiles of ``test_localize.py`` (70 degree cliff,
narrow ridge, grazing rays) resampled onto lon/lat grids, with voids, coverage edges, the
geoid and every interpolation; and the compiled kernel against its numpy reference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import pytest
from affine import Affine

import geoblock
from geoblock import ParameterSet, SensorModelBase, Status
from geoblock.dem import _raycast as raycast
from geoblock.dem import intersect
from geoblock.dem.array import ArrayDem

RES = 1e-4  # degrees (about 8 x 11 m)
# the straight-ray camera of test_localize.py (a module of its own: tests import nothing
# from each other)
TMERC = "+proj=tmerc +lat_0=43.7 +lon_0=7.05 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
GSD = 10.0


class LineCamera(SensorModelBase):
    """Straight rays in the TMERC plane: x = x0 + gsd col - k h, y = y0 - gsd row."""

    name: ClassVar[str] = "test-line-camera-raycast"

    def __init__(self, k: float, x0: float = -2000.0, y0: float = 1000.0) -> None:
        self.k, self.x0, self.y0 = float(k), float(x0), float(y0)

    shape = (200, 400)
    height_range = (-100.0, 3000.0)
    parameters = ParameterSet.empty()

    def with_parameters(self, values):
        return self

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.name, "k": self.k, "x0": self.x0, "y0": self.y0}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]):
        return cls(data["k"], data["x0"], data["y0"])

    def xy(self, row, col, h):
        return (self.x0 + GSD * np.asarray(col) - self.k * np.asarray(h),
                self.y0 - GSD * np.asarray(row))

    def image_to_ground(self, row, col, h):
        x, y = self.xy(row, col, h)
        lon, lat = geoblock.coords.transformer(TMERC, "EPSG:4326").transform(x, y)
        return np.asarray(lon), np.asarray(lat)


def cliff(x):
    """Flat at 100 m, then a 70 degree cliff up to 1100 m, then a plateau."""
    return np.clip(100.0 + math.tan(math.radians(70.0)) * x, 100.0, 1100.0)


def lonlat_dem(z_of_x, *, interpolation="bilinear", voids=None, geoid=None,
               box=(7.0, 43.68, 7.10, 43.72)):
    """An ArrayDem in EPSG:4326 whose heights are ``z_of_x`` of the TMERC x of each post."""
    west, south, east, north = box
    cols = int(round((east - west) / RES))
    rows = int(round((north - south) / RES))
    lon = west + (np.arange(cols) + 0.5) * RES
    lat = north - (np.arange(rows) + 0.5) * RES
    glon, glat = np.meshgrid(lon, lat)
    x, _ = geoblock.coords.transformer("EPSG:4326", TMERC).transform(glon, glat)
    z = np.asarray(z_of_x(np.asarray(x)), np.float64)
    if voids is not None:
        z[voids(glon, glat)] = np.nan
    kwargs = {"vertical": "geoid", "geoid": geoid} if geoid is not None else {
        "vertical": "ellipsoid"}
    return ArrayDem(z, Affine(RES, 0, west, 0, -RES, north), "EPSG:4326",
                    interpolation=interpolation, **kwargs)


def both_paths(monkeypatch, model, row, col, dem, **kw):
    """(fast result, reference result, the outcomes of the compiled scan)."""
    outcomes = []
    real_scan = raycast.scan

    def spy(*args, **kwargs):
        out = real_scan(*args, **kwargs)
        outcomes.append(out[0])
        return out

    monkeypatch.setattr(raycast, "scan", spy)
    fast = geoblock.localize(model, row, col, dem, warn=False, **kw)
    monkeypatch.setattr(intersect, "_FAST_SCAN", False)
    ref = geoblock.localize(model, row, col, dem, warn=False, **kw)
    monkeypatch.setattr(intersect, "_FAST_SCAN", True)
    seen = np.concatenate(outcomes) if outcomes else np.zeros(0, np.uint8)
    return fast, ref, seen


def assert_same(fast, ref, along_tol):
    (gf, sf), (gr, sr) = fast, ref
    np.testing.assert_array_equal(sf, sr)
    ok = sf == 0
    # both within the tolerance of the same root (along the ray)
    np.testing.assert_allclose(gf.h[ok], gr.h[ok], atol=along_tol)
    scale = math.cos(math.radians(43.7)) * 111_320.0
    assert np.all(np.abs(gf.lon[ok] - gr.lon[ok]) * scale <= 2 * along_tol)
    assert np.all(np.abs(gf.lat[ok] - gr.lat[ok]) * 111_320.0 <= 2 * along_tol)


def ridge(x):
    return 100.0 + np.clip(800.0 - math.tan(math.radians(70.0)) * np.abs(x), 0.0, 600.0)


def grazing(x):
    return np.clip(2000.0 - 0.95 / 1.2 * (x + 3000.0), 100.0, 2000.0)


CASES = {
    "cliff": (math.tan(math.radians(25.0)), cliff, np.linspace(160, 260, 41)),
    "ridge": (1.0, ridge, np.linspace(150, 300, 31)),
    "grazing": (1.2, grazing, np.linspace(141, 151, 11)),
    "gentle": (0.3, lambda x: 400 + 150 * np.sin(x / 500.0), np.linspace(20, 380, 37)),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("interpolation", ["bilinear", "bicubic"])
def test_steep_terrain_first_crossing_as_the_exact_scan(monkeypatch, case, interpolation):
    k, profile, col = CASES[case]
    cam = LineCamera(k=k)
    dem = lonlat_dem(profile, interpolation=interpolation)
    rows = np.linspace(10, 190, 7)
    row, col = (a.ravel() for a in np.meshgrid(rows, col))
    fast, ref, seen = both_paths(monkeypatch, cam, row, col, dem, tolerance_m=1e-4)
    assert np.mean(ref[1] == 0) > 0.9, np.bincount(ref[1])
    assert_same(fast, ref, 1e-3)
    # the compiled scan decided most rays itself (certain brackets)
    assert seen.size == row.size and np.mean(seen == raycast.BRACKET) > 0.5
    # on the ray (the camera's own straight line) and on the DEM
    g, s = fast
    ok = s == 0
    x, y = geoblock.coords.transformer("EPSG:4326", TMERC).transform(g.lon[ok], g.lat[ok])
    xe, ye = cam.xy(row[ok], col[ok], g.h[ok])
    np.testing.assert_allclose(x, xe, atol=1e-6)
    np.testing.assert_allclose(y, ye, atol=1e-6)
    assert np.all(np.abs(g.h[ok] - dem.height(g.lon[ok], g.lat[ok])) <= 1e-4)


def test_voids_and_coverage_edges_give_the_exact_scans_statuses(monkeypatch):
    """Rays that cross the terrain in a void (NO_DEM), rays that leave the coverage, rays
    that meet the terrain next to a void: the same statuses and points on both paths."""
    cam = LineCamera(k=0.6)

    def holes(lon, lat):
        return ((lon - 7.05) ** 2 + ((lat - 43.70) * 1.4) ** 2 < 0.004 ** 2) | (
            (lon > 7.02) & (lon < 7.024))

    dem = lonlat_dem(lambda x: 500 + 300 * np.sin(x / 700.0), voids=holes,
                     box=(7.0, 43.685, 7.08, 43.715))  # narrower than the image footprint
    row, col = (a.ravel() for a in np.meshgrid(np.linspace(0, 199, 40),
                                               np.linspace(0, 399, 80)))
    fast, ref, seen = both_paths(monkeypatch, cam, row, col, dem)
    statuses = np.bincount(ref[1], minlength=8)
    assert statuses[Status.CONVERGED] > 0 and statuses[Status.NO_DEM] > 0, statuses
    assert_same(fast, ref, 2e-3)
    assert np.any(seen == raycast.UNSURE)  # the exact scan took over somewhere


def test_geoid_dem_as_the_exact_scan(monkeypatch, egm96_path):
    if not egm96_path.exists():
        pytest.skip(f"no EGM96 grid at {egm96_path}")
    cam = LineCamera(k=0.5)
    dem = lonlat_dem(lambda x: 300 + 200 * np.cos(x / 400.0), geoid=egm96_path)
    row, col = (a.ravel() for a in np.meshgrid(np.linspace(5, 195, 20),
                                               np.linspace(5, 395, 40)))
    fast, ref, seen = both_paths(monkeypatch, cam, row, col, dem, tolerance_m=1e-4)
    assert np.all(ref[1] == 0)
    assert_same(fast, ref, 1e-3)
    assert np.mean(seen == raycast.BRACKET) > 0.9
    window = dem._ray_window((7.0, 43.68, 7.1, 43.72))
    lon = np.random.default_rng(1).uniform(7.01, 7.09, 1000)
    lat = np.random.default_rng(2).uniform(43.69, 43.71, 1000)
    # the compiled heights (N at the point) are the DEM's
    np.testing.assert_allclose(raycast.heights(window, lon, lat), dem.height(lon, lat),
                               atol=1e-9, rtol=0)
    # the geoid-corrected posts stay within the stated bound of those heights
    assert 0 < window.geoid_err < 0.05


def test_nearest_and_projected_dems_take_the_exact_scan(utm_tif):
    near = lonlat_dem(lambda x: 400 + 0.2 * x, interpolation="nearest")
    assert near._ray_window((7.0, 43.68, 7.1, 43.72)) is None
    utm = geoblock.open_dem(utm_tif[0], vertical="ellipsoid")
    assert utm._ray_window(utm.bounds) is None


def test_compiled_scan_agrees_with_its_numpy_reference():
    rng = np.random.default_rng(5)
    dem = lonlat_dem(lambda x: 600 + 250 * np.sin(x / 300.0) + 0.1 * x,
                     voids=lambda lon, lat: (np.abs(lon - 7.06) < 0.0015) & (lat > 43.70))
    window = dem._ray_window((7.0, 43.68, 7.1, 43.72))
    n = 400
    nodes = np.array([-100.0, 900.0, 1900.0, 150.0])
    lon_ground = rng.uniform(7.005, 7.095, n)
    lat_ground = rng.uniform(43.685, 43.715, n)
    k = rng.uniform(0.0, 2.0, n) * 1e-5  # degrees per metre of height
    curve = rng.uniform(-1, 1, n) * 1e-11  # a little curvature (and a cubic term)
    hs = nodes[:, None]
    lon4 = lon_ground + k * hs + curve * hs ** 2 + 1e-15 * hs ** 3
    lat4 = lat_ground + 0.3 * k * hs
    known = rng.uniform(size=n) > 0.05
    top = np.full(n, 1800.0)
    bottom = np.full(n, 0.0)
    step = rng.uniform(5.0, 50.0, n)
    nlev = np.ceil(1800.0 / step - 1e-9).astype(np.int64)
    got = raycast.scan(window, nodes, lon4, lat4, known, top, bottom, step, nlev, 1e-5, 60)
    want = raycast.scan_reference(window, nodes, lon4, lat4, known, top, bottom, step, nlev)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert set(np.unique(got[0])) >= {raycast.BRACKET, raycast.UNSURE, raycast.INELIGIBLE}
    # every certain bracket was refined on the approximate ray, inside its levels
    br = got[0] == raycast.BRACKET
    assert np.all(got[4][br] == raycast.REFINED)
    j = got[1][br]
    upper = top[br] - (j - 1) * step[br]
    lower = np.where(j >= nlev[br], bottom[br], top[br] - j * step[br])
    assert np.all((got[2][br] <= upper) & (got[2][br] >= lower))


def test_ventoux_fast_and_exact_scans_agree(monkeypatch, data_dir):
    shareloc = data_dir / "shareloc"
    srtm = shareloc / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    if not srtm.exists():
        pytest.skip(f"no Ventoux data at {shareloc}")
    model = geoblock.open_model(shareloc / "rectification/left_image.geom")
    dem = geoblock.open_dem(srtm, geoid=shareloc / "dtm/geoid/egm96_15.gtx", nodata="fill")
    rng = np.random.default_rng(0)
    row = rng.uniform(0, model.shape[0] - 1, 3000)
    col = rng.uniform(0, model.shape[1] - 1, 3000)
    fast, ref, seen = both_paths(monkeypatch, model, row, col, dem)
    assert np.all(ref[1] == 0)
    assert_same(fast, ref, 2e-3)
    assert np.mean(seen == raycast.BRACKET) > 0.99
    g = fast[0]
    (r, c), _ = model.project_with_status(g.lon, g.lat, g.h)
    assert np.hypot(r - row, c - col).max() < 1e-7
    assert np.abs(g.h - dem.height(g.lon, g.lat)).max() <= 1e-3


def test_whole_world_dem_across_its_west_edge(monkeypatch, data_dir):
    """A raster from -180 to 180 degrees under a scene across the antimeridian (GDAL's
    test_transformer_15 RPC): rays on both sides of the raster's west edge, where sampling
    wraps; the fast and the exact scans give the same answers."""
    rpc = data_dir / "gdal-autotest/extracted/transformer_15_rpc.vrt"
    if not rpc.exists():
        pytest.skip(f"no {rpc}")
    model = geoblock.open_model(rpc)
    step = 0.02
    lon = -180.0 + step * (np.arange(18000) + 0.5)
    lat = 1.0 - step * (np.arange(100) + 0.5)
    heights = 50.0 + 40.0 * np.sin(lon / 0.01)[None, :] * np.cos(lat / 0.013)[:, None]
    dem = ArrayDem(heights, Affine(step, 0, -180.0, 0, -step, 1.0), "EPSG:4326",
                   vertical="ellipsoid")
    rows, cols = model.shape
    row, col = (a.ravel() for a in np.meshgrid(np.linspace(-0.5, rows - 0.5, 15),
                                               np.linspace(-0.5, cols - 0.5, 15)))
    fast, ref, seen = both_paths(monkeypatch, model, row, col, dem, tolerance_m=1e-4)
    assert np.all(ref[1] == 0)
    np.testing.assert_array_equal(fast[1], ref[1])
    np.testing.assert_allclose(fast[0].h, ref[0].h, atol=1e-3)
    dlon = (fast[0].lon - ref[0].lon + 180.0) % 360.0 - 180.0
    assert np.abs(dlon).max() < 1e-7 and np.abs(fast[0].lat - ref[0].lat).max() < 1e-7
    # both sides of the line among the answers, and the compiled scan served most rays
    assert (fast[0].lon > 179.0).any() and (fast[0].lon < -179.0).any()
    assert np.mean(seen == raycast.BRACKET) > 0.5
