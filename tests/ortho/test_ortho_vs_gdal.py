"""geoblock's ortho against ``gdalwarp -rpc -to RPC_DEM=... -et 0`` on the same grid (issue 5).

Data: the shareloc Ventoux Pleiades crop (``image/phr_ventoux/left_image.tif``, 500 x 500) and
its RPC (``rpc/phr_ventoux/left_image.geom``, crop offset folded in by
``crop_from_geotransform=True``), SRTM ``N44E005.hgt`` + EGM96 ``egm96_15.gtx``.

Set-up, shared by GDAL and geoblock:

* source: a GeoTIFF copy of the crop carrying the crop model's RPC in its GDAL RPC tags
  (``geoblock.write_model(model, tif, format="gtiff")``), and a "coordinate image" with the
  same RPC: two float64 bands holding the source row and the source column of each pixel
  centre;
* DEM: SRTM + EGM96 heights computed by geoblock on the SRTM posts over the scene, written
  as an ellipsoidal EPSG:4979 GeoTIFF (pixel-is-area, one pixel per post) that GDAL reads as
  ``RPC_DEM`` and geoblock as ``open_dem(..., vertical="ellipsoid")``: both use the same
  heights with the same bilinear interpolation;
* grid: UTM 31N, 0.5 m, the crop's footprint shrunk by 20 m, through
  ``OutputGrid.from_bounds`` (= gdalwarp's ``-t_srs EPSG:32631 -tr 0.5 0.5 -te ...``);
* GDAL: ``GDALWarp`` (the library behind ``gdalwarp``; rasterio's libgdal through ctypes)
  with ``-rpc -to RPC_DEM=dem.tif -et 0 -r bilinear -to RPC_PIXEL_ERROR_THRESHOLD=1e-6``.
  The threshold only tightens GDAL's *image -> ground* iteration (default 0.1 px); a warp
  evaluates the RPC in the *ground -> image* direction, which is closed form, so it does not
  change the result (checked: identical outputs with and without it);
* geoblock: ``orthorectify(..., kernel="bilinear", tolerance_px=0.01)``.

Bilinear resampling reproduces a linear function exactly, so the warped coordinate image
holds, at every output pixel, the source (row, col) that each warper computed for it; their
difference is the geometric disagreement in source pixels.

Measured here (GDAL 3.10.3, rasterio 1.4.4), 492 x 463 output, interior pixels (valid in
both, source coordinates at least 1 px inside the crop): disagreement max 4.0e-5 px, median
3.0e-5 px, p99 3.7e-5 px; mean (d_row, d_col) = (-2.1e-5, -1.3e-5) px. GDAL -et 0 and
geoblock with ``tolerance_px=0`` (exact) agree to < 1e-4 px; the 4e-5 px is geoblock's lattice
interpolation (well inside its 0.01 px tolerance). Real image: |difference| <= 1 DN (the
rounding of the bilinear value to uint16), mean 0.001 DN.

Systematic differences, and why there are none here:

* half pixel: geoblock's (row, col) index pixel centres (row 0 = centre of the first row);
  GDAL's RPC transformer returns pixel/line with the corner convention (RPC line + 0.5) and
  its kernels put pixel i's centre at i + 0.5. Both sample the same point; a convention error
  would show as a uniform 0.5 px shift in both axes (measured: 2e-5 px);
* DEM sampling: both read the same ellipsoidal posts with bilinear interpolation and the
  pixel-is-area convention (post at the pixel centre). Sampling the SRTM tile and the geoid
  in geoblock directly instead of this intermediate grid changes the source coordinates by
  4e-10 px (asserted < 0.01 px): the intermediate grid holds exactly geoblock's heights at
  the posts, and both interpolate them bilinearly;
* geoid: ``gdalwarp -to RPC_DEM=N44E005.hgt`` on the raw SRTM tile treats its EGM96 heights as
  ellipsoidal (the tile's CRS has no vertical datum, so GDAL applies no vertical shift): the
  ~50 m geoid undulation at Ventoux then shifts the whole ortho by ~15.6 px, uniformly, i.e.
  exactly the model's parallax for -N metres. Hence the ellipsoidal DEM given to both.

``-et 0.125`` (gdalwarp's default without RPC_DEM) is no longer exact: measured max 3.8 px,
p99 2.4 px against geoblock on this relief, far over its nominal 0.125 px.
"""

from __future__ import annotations

import ctypes
import glob
import os
import warnings

import numpy as np
import pytest

import geoblock

rasterio = pytest.importorskip("rasterio")
from affine import Affine  # noqa: E402  (rasterio's dependency)
from rasterio.errors import NotGeoreferencedWarning  # noqa: E402

from geoblock.ortho import OutputGrid, orthorectify  # noqa: E402

UTM = "EPSG:32631"
RES = 0.5
SRTM_RES = 1.0 / 1200.0
TOL = 0.05  # px, issue 5


# ------------------------------------------------------------------------------ GDAL
def _libgdal():
    """rasterio's own libgdal (already loaded by rasterio), through ctypes."""
    libs = glob.glob(os.path.join(os.path.dirname(os.path.dirname(rasterio.__file__)),
                                  "rasterio.libs", "libgdal*.so*"))
    if not libs:
        pytest.skip("rasterio's bundled libgdal not found (GDALWarp through ctypes)")
    lib = ctypes.CDLL(libs[0])
    lib.GDALAllRegister()
    vp, cp = ctypes.c_void_p, ctypes.c_char_p
    lib.GDALOpen.restype, lib.GDALOpen.argtypes = vp, [cp, ctypes.c_int]
    lib.GDALWarpAppOptionsNew.restype = vp
    lib.GDALWarpAppOptionsNew.argtypes = [ctypes.POINTER(cp), vp]
    lib.GDALWarpAppOptionsFree.argtypes = [vp]
    lib.GDALWarp.restype = vp
    lib.GDALWarp.argtypes = [cp, vp, ctypes.c_int, ctypes.POINTER(vp), vp,
                             ctypes.POINTER(ctypes.c_int)]
    lib.GDALClose.argtypes = [vp]
    return lib


def gdalwarp(src, dst, dem, grid, *, et=0.0, nodata="nan", extra=()):
    """``gdalwarp -t_srs -tr -te -r bilinear -rpc -to RPC_DEM=dem -et ET``: the array."""
    lib = _libgdal()
    xmin, ymin, xmax, ymax = grid.bounds
    xres, yres = grid.resolution
    args = ["-overwrite", "-of", "GTiff", "-t_srs", grid.crs.to_wkt(),
            "-tr", repr(xres), repr(yres), "-te", repr(xmin), repr(ymin), repr(xmax), repr(ymax),
            "-r", "bilinear", "-rpc", "-to", f"RPC_DEM={dem}", "-et", repr(float(et)),
            "-dstnodata", nodata, *extra]
    argv = (ctypes.c_char_p * (len(args) + 1))(*[a.encode() for a in args], None)
    opts = lib.GDALWarpAppOptionsNew(argv, None)
    handle = lib.GDALOpen(str(src).encode(), 0)
    assert opts and handle
    try:
        out = lib.GDALWarp(str(dst).encode(), None, 1, (ctypes.c_void_p * 1)(handle), opts,
                           ctypes.byref(ctypes.c_int(0)))
        assert out, "GDALWarp failed"
        lib.GDALClose(out)
    finally:
        lib.GDALClose(handle)
        lib.GDALWarpAppOptionsFree(opts)
    with rasterio.open(dst) as ds:
        assert ds.shape == grid.shape  # gdalwarp's -te/-tr grid is OutputGrid.from_bounds
        assert tuple(ds.transform)[:6] == pytest.approx(tuple(grid.transform)[:6], abs=1e-9)
        return ds.read()


# ------------------------------------------------------------------------------ set-up
def _write_raster(path, data, **kw):
    data = np.asarray(data)
    if data.ndim == 2:
        data = data[None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", count=data.shape[0], height=data.shape[1],
                           width=data.shape[2], dtype=data.dtype, **kw) as ds:
            ds.write(data)
    return str(path)


@pytest.fixture(scope="module")
def ventoux(data_dir, tmp_path_factory):
    shareloc = data_dir / "shareloc"
    crop = shareloc / "image/phr_ventoux/left_image.tif"
    model = geoblock.open_model(shareloc / "rpc/phr_ventoux/left_image.geom", image=crop,
                                crop_from_geotransform=True)
    hgt = shareloc / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    geoid_dem = geoblock.open_dem(hgt, geoid=shareloc / "dtm/geoid/egm96_15.gtx", nodata="fill")
    tmp = tmp_path_factory.mktemp("ortho_vs_gdal")

    # GDAL-usable sources: no (pixel-unit) geotransform, the crop's RPC in the GDAL RPC tags
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(crop) as ds:
            pixels = ds.read(1)
    rows, cols = pixels.shape
    assert model.shape == (rows, cols)
    source = _write_raster(tmp / "ventoux_rpc.tif", pixels)
    coords = np.stack(np.meshgrid(np.arange(rows, dtype="float64"),
                                  np.arange(cols, dtype="float64"), indexing="ij"))
    coord_image = _write_raster(tmp / "ventoux_coords.tif", coords)
    for path in (source, coord_image):
        geoblock.write_model(model, path, format="gtiff")
        with rasterio.open(path) as ds:
            assert ds.rpcs is not None and ds.rpcs.line_off == pytest.approx(model.rpc.line_off)

    # the scene's footprint in UTM 31N; the output grid: 0.5 m, 20 m inside it
    footprint = OutputGrid.for_model(model, geoid_dem, crs=UTM)
    x0, y0, x1, y1 = footprint.bounds
    grid = OutputGrid.from_bounds(UTM, (x0 + 20, y0 + 20, x1 - 20, y1 - 20), RES)

    # SRTM + EGM96 -> ellipsoidal heights on the SRTM posts over the footprint (+ ~1 km)
    lon, lat = (np.asarray(v) for v in
                geoblock.coords.transformer(UTM, "EPSG:4326").transform([x0, x1, x0, x1],
                                                                        [y0, y0, y1, y1]))
    margin = 0.01
    c0 = int(np.floor((lon.min() - margin - 5.0) / SRTM_RES))
    c1 = int(np.ceil((lon.max() + margin - 5.0) / SRTM_RES))
    r0 = int(np.floor((45.0 - lat.max() - margin) / SRTM_RES))
    r1 = int(np.ceil((45.0 - lat.min() + margin) / SRTM_RES))
    post_lon = 5.0 + np.arange(c0, c1 + 1) * SRTM_RES
    post_lat = 45.0 - np.arange(r0, r1 + 1) * SRTM_RES
    heights = geoid_dem.height(*np.meshgrid(post_lon, post_lat))
    assert np.all(np.isfinite(heights))
    dem_path = _write_raster(
        tmp / "ventoux_ellipsoidal.tif", heights.astype("float64"), crs="EPSG:4979",
        transform=Affine(SRTM_RES, 0.0, post_lon[0] - SRTM_RES / 2, 0.0, -SRTM_RES,
                         post_lat[0] + SRTM_RES / 2),
    )
    dem = geoblock.open_dem(dem_path, vertical="ellipsoid")
    assert dem.height(post_lon[3], post_lat[5]) == pytest.approx(heights[5, 3], abs=1e-6)

    gb_coords = orthorectify(coord_image, model, dem, grid, kernel="bilinear",
                             tolerance_px=0.01, chunks=256).values
    return {"model": model, "grid": grid, "source": source, "coords": coord_image,
            "dem_path": dem_path, "dem": dem, "geoid_dem": geoid_dem, "hgt": str(hgt),
            "gb_coords": gb_coords, "tmp": tmp, "shape": (rows, cols)}


def _interior(ref, shape):
    rows, cols = shape
    return (np.isfinite(ref).all(0) & (ref[0] >= 1) & (ref[0] <= rows - 2)
            & (ref[1] >= 1) & (ref[1] <= cols - 2))


def _disagreement(other, ref, shape):
    """Per-pixel distance (source px) between two warped coordinate images, interior pixels,
    and the mean (d_row, d_col)."""
    inside = _interior(ref, shape) & np.isfinite(other).all(0)
    d = other - ref
    return np.hypot(d[0], d[1])[inside], (d[0][inside].mean(), d[1][inside].mean()), inside


# ------------------------------------------------------------------------------ tests
def test_geometry_agrees_with_gdalwarp_exact(ventoux):
    """Issue 5: <= 0.05 px (median, p99; max reported) on the coordinate image."""
    v = ventoux
    gdal = gdalwarp(v["coords"], v["tmp"] / "gdal_coords.tif", v["dem_path"], v["grid"],
                    et=0.0, extra=("-to", "RPC_PIXEL_ERROR_THRESHOLD=1e-6"))
    ref = v["gb_coords"]
    dist, (mean_dr, mean_dc), inside = _disagreement(gdal, ref, v["shape"])
    assert inside.mean() > 0.95  # nearly all the grid is inside the crop
    # the same valid pixels: only a few at the crop's edges differ
    assert (np.isfinite(gdal[0]) == np.isfinite(ref[0])).mean() > 0.99
    med, p99, mx = np.median(dist), np.percentile(dist, 99), dist.max()
    print(f"geoblock (tol 0.01) vs gdalwarp -et 0: max {mx:.2e} px, median {med:.2e} px, "
          f"p99 {p99:.2e} px, mean (d_row, d_col) = ({mean_dr:.1e}, {mean_dc:.1e}) px")
    assert med <= TOL and p99 <= TOL
    assert mx <= TOL
    # no half-pixel (or any other) systematic offset
    assert abs(mean_dr) < 1e-3 and abs(mean_dc) < 1e-3

    # without RPC_PIXEL_ERROR_THRESHOLD: the same (the warp only uses ground -> image)
    default = gdalwarp(v["coords"], v["tmp"] / "gdal_coords_default.tif", v["dem_path"],
                       v["grid"], et=0.0)
    np.testing.assert_array_equal(default, gdal)

    # geoblock exact per pixel: GDAL's -et 0 to round-off; the residual above is the lattice
    exact = orthorectify(v["coords"], v["model"], v["dem"], v["grid"], kernel="bilinear",
                         tolerance_px=0.0, chunks=256).values
    dist_exact, _, _ = _disagreement(gdal, exact, v["shape"])
    assert dist_exact.max() < 1e-4


def test_gdalwarp_approximate_transformer_is_not_exact(ventoux):
    """``-et 0.125``: the check above is sensitive (GDAL's approximation shows up)."""
    v = ventoux
    approx = gdalwarp(v["coords"], v["tmp"] / "gdal_coords_et.tif", v["dem_path"], v["grid"],
                      et=0.125)
    dist, _, _ = _disagreement(approx, v["gb_coords"], v["shape"])
    print(f"gdalwarp -et 0.125 vs geoblock: max {dist.max():.3f} px, "
          f"p99 {np.percentile(dist, 99):.3f} px")
    assert dist.max() > TOL


def test_real_image_values_agree_with_gdalwarp(ventoux):
    v = ventoux
    gdal = gdalwarp(v["source"], v["tmp"] / "gdal_image.tif", v["dem_path"], v["grid"],
                    et=0.0, nodata="0")[0].astype("float64")
    ours = orthorectify(v["source"], v["model"], v["dem"], v["grid"], kernel="bilinear",
                        tolerance_px=0.01, chunks=256).values[0].astype("float64")
    inside = _interior(v["gb_coords"], v["shape"])
    diff = np.abs(gdal - ours)[inside]
    print(f"real image: |GDAL - geoblock| max {diff.max():.0f} DN, mean {diff.mean():.4f} DN "
          f"(values {ours[inside].min():.0f}..{ours[inside].max():.0f})")
    assert diff.max() <= 1.0  # rounding of the bilinear value to uint16
    assert diff.mean() < 0.01


def test_dem_sampling_and_geoid_explain_the_offsets(ventoux):
    """The systematic differences one gets without a shared ellipsoidal DEM."""
    v = ventoux
    ref = v["gb_coords"]
    # DEM sampling: geoblock on SRTM + EGM96 directly vs the ellipsoidal posts: < 0.01 px
    direct = orthorectify(v["coords"], v["model"], v["geoid_dem"], v["grid"], kernel="bilinear",
                          tolerance_px=0.01, chunks=256).values
    dist, _, _ = _disagreement(direct, ref, v["shape"])
    print(f"geoblock SRTM+EGM96 directly vs ellipsoidal posts: max {dist.max():.2e} px")
    assert dist.max() < 0.01

    # geoid: GDAL on the raw SRTM tile (EGM96 heights read as ellipsoidal) is shifted by the
    # model's parallax for the geoid undulation N, uniformly
    raw = gdalwarp(v["coords"], v["tmp"] / "gdal_coords_raw.tif", v["hgt"], v["grid"], et=0.0)
    dist, (mean_dr, mean_dc), _ = _disagreement(raw, ref, v["shape"])
    rows, cols = v["shape"]
    g, status = geoblock.localize(v["model"], (rows - 1) / 2, (cols - 1) / 2, v["dem"])
    ellipsoidal = geoblock.open_dem(v["hgt"], vertical="ellipsoid", nodata="fill")
    undulation = float(v["geoid_dem"].height(g.lon, g.lat) - ellipsoidal.height(g.lon, g.lat))
    (r0, c0), _ = v["model"].project_with_status(g.lon, g.lat, g.h)
    (r1, c1), _ = v["model"].project_with_status(g.lon, g.lat, g.h - undulation)
    parallax = float(np.hypot(r1 - r0, c1 - c0))
    print(f"raw SRTM in GDAL: shift median {np.median(dist):.2f} px, mean (d_row, d_col) = "
          f"({mean_dr:.2f}, {mean_dc:.2f}) px; geoid N = {undulation:.2f} m -> "
          f"parallax {parallax:.2f} px")
    assert 40.0 < undulation < 60.0
    assert abs(np.median(dist) - parallax) < 0.1
    assert np.percentile(dist, 99) - np.percentile(dist, 1) < 0.1  # uniform
