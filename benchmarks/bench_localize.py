"""localize throughput: image points -> ground on a DEM, for an RPC model, against GDAL.

Run: ``python benchmarks/bench_localize.py [--points N] [--repeat R] [--quick]``.

Two set-ups: the synthetic ``RpcModel.example()`` (10 000 x 12 000 px near Nice) over a
30 m synthetic GridDem with 800 m of relief, and (when the shared data is present) the
Ventoux Pleiades RPC (``shareloc/rectification/left_image.geom``) over SRTM N44E005 + EGM96.
For each: points per second (after a warm-up; best and median of ``--repeat`` calls, the
methods interleaved) of ``method="robust"`` (the compiled scan of approximate rays, then the
exact ray: the default), of the same with the exact scan alone (the numpy reference path) and
of ``"ray-tracing"``, the statuses, and the accuracy: the maximum ``|h - dem(lon, lat)|`` and
the back-projection residual in pixels.

The peer, on the Ventoux set-up: GDAL's RPC transformer with ``RPC_DEM`` (rasterio's
``RPCTransformer(rpcs, RPC_DEM=..., RPC_DEMINTERPOLATION="bilinear",
RPC_PIXEL_ERROR_THRESHOLD=1e-8, RPC_MAX_ITERATIONS=50)``, ``xy(row, col, 0,
offset="center")``). Vertical datum: GDAL is given the DEM already converted to ellipsoidal
heights (``dem.height`` at the post centres = post + EGM96 ``N`` there, a float64 GeoTIFF in a
temporary directory). Its ``RPC_DEM_APPLY_VDATUM_SHIFT`` (which adds ``N`` at the point, as
geoblock does) needs PROJ to find the geoid grid: with rasterio's bundled PROJ, a DEM SRS
naming ``egm96_15.gtx`` by ``+geoidgrids`` (absolute path, or through ``PROJ_DATA``) was
refused ("vgridshift: could not find required grid(s)"), so it is not used. geoblock reads
the original SRTM tile + EGM96 (``N`` at the point); the two surfaces differ by about 1e-6 m
(printed). Agreement: the horizontal distance between GDAL's and geoblock's points (both
converged), and GDAL's own back-projection residual (at the DEM height under its point).
shareloc's C++ DTM intersection is timed too when shareloc is importable
(:func:`shareloc_localizer`); its intersection approximates the line of sight, so its
back-projection residual is printed beside the others.
``cpu ms``: the process's CPU time per call (median): geoblock's kernels run on the numba
threads (2 here), GDAL's transformer on one.

``--whole`` times whole commands instead (start-up included): ``--child geoblock`` /
``--child gdal`` localise ``--points`` random points of the Ventoux image from a cold
process, with the files ``--prepare DIR`` writes (the ellipsoidal DEM and the RPC as GDAL
metadata, JSON); pair them with any whole-process timer.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))
SHARELOC = DATA_DIR / "shareloc"
GEOM = SHARELOC / "rectification/left_image.geom"
SRTM = SHARELOC / "dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GTX = SHARELOC / "dtm/geoid/egm96_15.gtx"
M_PER_DEG = 111_319.49


def points(shape, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, shape[0] - 1, n), rng.uniform(0, shape[1] - 1, n)


def synthetic():
    from geoblock_rpc.model import RpcModel

    from geoblock.dem import GridDem

    model = RpcModel.example()
    res = 30.0 / 111_000
    lon0, lat0, n = 6.98, 43.78, 1000
    lon = lon0 + (np.arange(n) + 0.5) * res
    lat = lat0 - (np.arange(n) + 0.5) * res
    x, y = np.meshgrid(lon, lat)
    z = 600 + 400 * np.sin(x * 300) * np.cos(y * 200)
    return "RpcModel.example() + 30 m synthetic GridDem", model, GridDem(
        z, (res, 0, lon0, 0, -res, lat0), "EPSG:4326")


def ventoux():
    import geoblock

    model = geoblock.open_model(GEOM)
    dem = geoblock.open_dem(SRTM, geoid=GTX, nodata="fill")
    return "Ventoux Pleiades RPC + SRTM 90 m + EGM96", model, dem


def prepare(model, dem, directory: Path) -> tuple[Path, Path]:
    """The ellipsoidal DEM (GeoTIFF) and the RPC (GDAL metadata, JSON) for GDAL."""
    import rasterio

    with rasterio.open(SRTM) as src:
        shape, transform = src.shape, src.transform
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    lon = transform.c + (cols + 0.5) * transform.a
    lat = transform.f + (rows + 0.5) * transform.e
    heights = dem.height(lon, lat)
    tif = directory / "N44E005_ellipsoidal.tif"
    with rasterio.open(tif, "w", driver="GTiff", height=shape[0], width=shape[1], count=1,
                       dtype="float64", crs="EPSG:4326", transform=transform) as dst:
        dst.write(heights, 1)
    rpc = directory / "left_image_rpc.json"
    rpc.write_text(json.dumps(model.rpc.to_gdal()))
    return tif, rpc


def gdal_transformer(rpc_json: Path, tif: Path):
    from rasterio.rpc import RPC
    from rasterio.transform import RPCTransformer

    rpcs = RPC.from_gdal(json.loads(rpc_json.read_text()))
    return RPCTransformer(rpcs, RPC_DEM=str(tif), RPC_DEMINTERPOLATION="bilinear",
                          RPC_PIXEL_ERROR_THRESHOLD=1e-8, RPC_MAX_ITERATIONS=50)


def shareloc_localizer(row, col):
    """shareloc's C++ DTM intersection (``RPCoptim.direct_loc_dtm`` over
    ``bindings_cpp.DTMIntersection``, SRTM + EGM96 through its ``dtm_reader``, voids filled by
    ``rio_fillnodata`` as geoblock's ``nodata="fill"``), or None when shareloc is not
    importable (install it apart: ``pip install --no-deps --target DIR shareloc``, then
    ``PYTHONPATH=DIR``). shareloc's pixel centres are at +0.5 (its top-left convention)."""
    try:
        import bindings_cpp
        from shareloc.dtm_reader import dtm_reader
        from shareloc.geomodels import GeoModel
    except Exception:  # noqa: BLE001 - any import failure: no peer
        return None
    model = GeoModel(str(GEOM), "RPCoptim")
    dtm = dtm_reader(str(SRTM), str(GTX), roi=None, roi_is_in_physical_space=True,
                     fill_nodata="rio_fillnodata", fill_value=0.0)
    cpp = bindings_cpp.DTMIntersection(dtm.epsg, dtm.alt_data, dtm.nb_rows, dtm.nb_columns,
                                       dtm.transform)
    return lambda: model.direct_loc_dtm(row + 0.5, col + 0.5, cpp)


def residual(model, row, col, lon, lat, h):
    (r, c), _ = model.project_with_status(lon, lat, h)
    return np.hypot(r - row, c - col)


def run(name, model, dem, n, repeat, peer_dir: Path | None) -> None:
    import warnings

    import geoblock
    from geoblock.dem import intersect

    row, col = points(model.shape, n)
    print(f"\n{name}: {n} points")

    def geoblock_call(method, fast=True):
        def call():
            intersect._FAST_SCAN = fast
            try:
                return geoblock.localize(model, row, col, dem, method=method, warn=False)
            finally:
                intersect._FAST_SCAN = True
        return call

    calls = {"robust (default)": geoblock_call("robust"),
             "robust, exact scan (reference)": geoblock_call("robust", fast=False),
             "ray-tracing": geoblock_call("ray-tracing")}
    tr = None
    if peer_dir is not None:
        tif, rpc_json = prepare(model, dem, peer_dir)
        tr = gdal_transformer(rpc_json, tif)
        zeros = np.zeros(n)

        def gdal_call():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return tr.xy(row, col, zeros, offset="center")
        calls["GDAL RPC_DEM (rasterio), 1e-8 px"] = gdal_call
        shareloc_call = shareloc_localizer(row, col)
        if shareloc_call is not None:
            calls["shareloc C++ direct_loc_dtm"] = shareloc_call
    results = {k: f() for k, f in calls.items()}  # warm-up
    times: dict[str, list[float]] = {k: [] for k in calls}
    cpu: dict[str, list[float]] = {k: [] for k in calls}
    for _ in range(repeat):  # interleaved
        for k, f in calls.items():
            t, c = time.perf_counter(), time.process_time()
            results[k] = f()
            times[k].append(time.perf_counter() - t)
            cpu[k].append(time.process_time() - c)
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} (1 and 5 min)")
    print(f"{'method':<34} {'kpts/s best':>11} {'median':>8} {'cpu ms':>7} {'ok':>7} "
          f"{'max|h-dem| m':>12} {'max resid px':>12} {'vs geoblock m':>13}")
    ref = results["robust (default)"][0]
    ok_ref = results["robust (default)"][1] == 0
    for k, out in results.items():
        best, med = min(times[k]), statistics.median(times[k])
        if k.startswith("GDAL"):
            lon, lat = (np.asarray(v, float) for v in out)
            ok = np.isfinite(lon) & np.isfinite(lat)
            h = np.full(n, np.nan)
            h[ok] = dem.height(lon[ok], lat[ok])
        elif k.startswith("shareloc"):
            lon, lat, h = (np.asarray(out[:, i], float) for i in range(3))
            ok = np.isfinite(lon) & np.isfinite(lat) & np.isfinite(h)
        else:
            g, status = out
            lon, lat, h = g.lon, g.lat, g.h
            ok = status == 0
        dz = np.abs(h[ok] - dem.height(lon[ok], lat[ok])).max() if ok.any() else np.nan
        dz_txt = "-" if k.startswith("GDAL") else f"{dz:.2e}"  # GDAL gives no h
        res = residual(model, row[ok], col[ok], lon[ok], lat[ok], h[ok]).max() \
            if ok.any() else np.nan
        both = ok & ok_ref
        scale = np.cos(np.radians(np.nanmean(ref.lat)))
        dist = np.hypot((lon[both] - ref.lon[both]) * scale, lat[both] - ref.lat[both]).max() \
            * M_PER_DEG if both.any() else np.nan
        print(f"{k:<34} {n / best / 1e3:>11.0f} {n / med / 1e3:>8.0f} "
              f"{1e3 * statistics.median(cpu[k]):>7.0f} {ok.sum():>7d} "
              f"{dz_txt:>12} {res:>12.2e} {dist:>13.2e}")
    if tr is not None:
        tr.close()
        # the two vertical datum conversions: N at the point (geoblock) or at the posts
        ell = geoblock.open_dem(peer_dir / "N44E005_ellipsoidal.tif", vertical="ellipsoid")
        g1, s1 = results["robust (default)"]
        g2, s2 = geoblock.localize(model, row, col, ell, warn=False)
        both = (s1 == 0) & (s2 == 0)
        scale = np.cos(np.radians(np.nanmean(g1.lat)))
        d = np.hypot((g1.lon - g2.lon)[both] * scale, (g1.lat - g2.lat)[both]) * M_PER_DEG
        print(f"geoblock on SRTM + EGM96 (N at the point) vs on the ellipsoidal GeoTIFF GDAL "
              f"reads (N at the posts): max {d.max():.2e} m horizontally, "
              f"{np.abs(g1.h - g2.h)[both].max():.2e} m in h")


def child(which: str, directory: Path, n: int) -> None:
    """One whole command: localise ``n`` random points of the Ventoux image."""
    if which == "geoblock":
        import geoblock

        model = geoblock.open_model(GEOM)
        dem = geoblock.open_dem(SRTM, geoid=GTX, nodata="fill")
        row, col = points(model.shape, n)
        _, status = geoblock.localize(model, row, col, dem, warn=False)
        print(int((status == 0).sum()))
    else:
        import warnings

        import rasterio

        with rasterio.Env(), warnings.catch_warnings():  # Env: GDAL's drivers registered
            warnings.simplefilter("ignore")
            tr = gdal_transformer(directory / "left_image_rpc.json",
                                  directory / "N44E005_ellipsoidal.tif")
            shape = (41801, 39182)  # the image of left_image.geom (rows, cols)
            row, col = points(shape, n)
            x, _ = tr.xy(row, col, np.zeros(n), offset="center")
        print(int(np.isfinite(np.asarray(x, float)).sum()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--quick", action="store_true", help="10^4 points, 1 timed call")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--prepare", type=Path, help="write GDAL's files into DIR and exit")
    parser.add_argument("--child", choices=("geoblock", "gdal"), help="one whole command")
    parser.add_argument("--dir", type=Path, help="the --prepare directory, for --child")
    args = parser.parse_args()
    n = 10_000 if args.quick else args.points
    repeat = 1 if args.quick else args.repeat
    if args.child:
        child(args.child, args.dir, n)
        return
    if args.prepare:
        args.prepare.mkdir(parents=True, exist_ok=True)
        _, model, dem = ventoux()
        print(*prepare(model, dem, args.prepare))
        return
    run(*synthetic(), n, repeat, None)
    if SRTM.is_file():
        with tempfile.TemporaryDirectory() as tmp:
            run(*ventoux(), n, repeat, Path(tmp))
    else:
        print(f"(Ventoux set-up skipped: no data at {DATA_DIR})", file=sys.stderr)


if __name__ == "__main__":
    main()
