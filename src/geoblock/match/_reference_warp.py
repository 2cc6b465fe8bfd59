"""One image against the reference orthoimage: the steps of :mod:`geoblock.match.reference`
(overlap, warp onto the reference's grid, tile shift, patch matching, outlier test, control
points)."""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError
from geoblock.match._reference_types import (
    CE90_FACTOR,
    CONSENSUS_PX,
    MAX_TILES,
    MIN_SIGMA_MATCH_PX,
    TILE_PX,
    ReferenceMatches,
    ReferenceOptions,
    ReferenceOrtho,
    reference_sigmas,
)
from geoblock.match.consistency import MAD_SCALE, consensus, consistent, scale_of

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.io.images import OpenedImage
    from geoblock.match.pipeline import MatchImage

#: Largest window of the reference matched against one image, pixels (memory: about 60 bytes
#: a pixel); a larger overlap is refused with the way out (a coarser reference).
MAX_WINDOW_PIXELS = 40_000_000
#: Image pixels read at once while area-averaging.
_STRIP_PIXELS = 1 << 22
#: Metres per degree of latitude (sphere of radius a), for the DEM's slope.
_DEG_M = math.radians(1.0) * 6378137.0
#: Fewest matches that can be tested for consistency.
MIN_MATCHES = 3


def _empty(im: MatchImage, status: str, **more: Any
           ) -> tuple[ReferenceMatches, dict[str, np.ndarray]]:
    rows = {k: np.zeros(0) for k in ("lon", "lat", "h", "slope", "row", "col")}
    return ReferenceMatches(im.id, status, **more), rows


def _footprint(im: MatchImage, ref: ReferenceOrtho, dem: DemSource
               ) -> tuple[tuple[int, int, int, int] | None, float]:
    """The window ``(r0, r1, c0, c1)`` of the reference the image's outline covers (None:
    none), and the image's mean height on the DEM."""
    from geoblock import coords
    from geoblock.dem.intersect import localize

    rows, cols = (int(v) for v in im.image.shape)
    r, c = np.meshgrid(np.linspace(0, rows - 1, 17), np.linspace(0, cols - 1, 17),
                       indexing="ij")
    g, status = localize(im.model, r.ravel(), c.ravel(), dem, warn=False)
    ok = (status == 0) & np.isfinite(g.lon) & np.isfinite(g.lat)
    if not ok.any():
        return None, math.nan
    x, y = coords.transformer("EPSG:4326", ref.crs).transform(g.lon[ok], g.lat[ok])
    t = ref.transform  # north-up: corner-based pixel coordinates
    col = (np.asarray(x) - t.c) / t.a
    row = (np.asarray(y) - t.f) / t.e
    if not (np.isfinite(row).all() and np.isfinite(col).all()):
        return None, math.nan
    r0 = max(0, int(math.floor(float(np.min(row)))))
    r1 = min(ref.shape[0], int(math.ceil(float(np.max(row)))))
    c0 = max(0, int(math.floor(float(np.min(col)))))
    c1 = min(ref.shape[1], int(math.ceil(float(np.max(col)))))
    h = float(np.nanmean(g.h[ok]))
    if r1 - r0 < 2 or c1 - c0 < 2:
        return None, h
    return (r0, r1, c0, c1), h


def _reduced(image: OpenedImage, window: tuple[int, int, int, int], f: int, band: int
             ) -> np.ndarray:
    """The image's ``window`` area-averaged over ``f x f`` blocks (a block with less than
    half its pixels valid is NaN), read in strips."""
    from geoblock.io.images import read_band

    r0, r1, c0, c1 = window
    nr, nc = (r1 - r0) // f, (c1 - c0) // f
    if f == 1:
        return read_band(image, window, band)
    out = np.empty((nr, nc))
    step = max(1, _STRIP_PIXELS // max(1, nc * f * f)) * f
    for s in range(0, nr * f, step):
        e = min(s + step, nr * f)
        px = read_band(image, (r0 + s, r0 + e, c0, c0 + nc * f), band)
        blocks = px.reshape((e - s) // f, f, nc, f)
        good = np.isfinite(blocks)
        count = good.sum(axis=(1, 3))
        total = np.where(good, blocks, 0.0).sum(axis=(1, 3))
        with np.errstate(invalid="ignore", divide="ignore"):
            out[s // f:e // f] = np.where(2 * count >= f * f, total / count, np.nan)
    return out


def _warp(im: MatchImage, grid: Any, dem: DemSource, f: int, band: int) -> np.ndarray:
    """The image on ``grid`` (NaN without data): the orthorectifier's source coordinates,
    the image area-averaged by ``f``, resampled bicubically."""
    from geoblock.ortho.kernels import resample
    from geoblock.ortho.lattice import source_coordinates

    rr, cc, valid = source_coordinates(im.model, dem, grid, tolerance_px=0.01 * f)
    out = np.full(grid.shape, np.nan)
    if not valid.any():
        return out
    rows, cols = (int(v) for v in im.image.shape)
    pad = 3 * f
    r0 = max(0, int(math.floor(float(rr[valid].min()))) - pad)
    r1 = min(rows, int(math.ceil(float(rr[valid].max()))) + pad + 1)
    c0 = max(0, int(math.floor(float(cc[valid].min()))) - pad)
    c1 = min(cols, int(math.ceil(float(cc[valid].max()))) + pad + 1)
    if r1 - r0 < f or c1 - c0 < f:
        return out
    small = _reduced(im.image, (r0, r1, c0, c1), f, band)
    half = (f - 1) / 2.0  # the centre of block i is raw pixel r0 + i f + (f - 1) / 2
    values, ok = resample(small[None], (rr - r0 - half) / f, (cc - c0 - half) / f, "bicubic",
                          nodata=math.nan)
    out[ok] = values[0][ok]
    return out


def _tile_shift(a: np.ndarray, b: np.ndarray, tile: int) -> tuple[float, float] | None:
    """The shift ``d`` with ``b(x) ~ a(x - d)`` most tiles agree on (phase correlation of
    tiles of the two windows, NaN filled), pixels; None when no tile has data in both."""
    rows, cols = a.shape
    t = min(tile, rows, cols)
    if t < 8:
        return None
    r_starts = np.arange(0, rows - t + 1, max(1, t // 2))
    c_starts = np.arange(0, cols - t + 1, max(1, t // 2))
    rs, cs = (v.ravel() for v in np.meshgrid(r_starts, c_starts, indexing="ij"))
    off = np.arange(t)
    ta = a[rs[:, None, None] + off[None, :, None], cs[:, None, None] + off[None, None, :]]
    tb = b[rs[:, None, None] + off[None, :, None], cs[:, None, None] + off[None, None, :]]
    both = np.isfinite(ta) & np.isfinite(tb)
    share = both.mean(axis=(1, 2))
    good = np.flatnonzero(share >= 0.5)
    if not good.size:  # a small or slanted overlap: its fullest tile, if a fifth has data
        best = int(np.argmax(share))
        if share[best] < 0.2:
            return None
        good = np.array([best])
    good = good[np.argsort(-share[good], kind="stable")][:MAX_TILES]
    ta, tb, both = ta[good], tb[good], both[good]
    window = np.hanning(t)[:, None] * np.hanning(t)[None, :]

    def prepared(v: np.ndarray) -> np.ndarray:
        mean = np.where(both, v, 0.0).sum(axis=(1, 2)) / both.sum(axis=(1, 2))
        return np.where(both, v - mean[:, None, None], 0.0) * window

    fa = np.fft.fft2(prepared(ta))
    fb = np.fft.fft2(prepared(tb))
    cross = fb * np.conj(fa)
    cross /= np.maximum(np.abs(cross), 1e-12)
    surface = np.fft.ifft2(cross).real
    flat = surface.reshape(surface.shape[0], -1)
    peak = np.argmax(flat, axis=1)
    pi, pj = np.divmod(peak, t)
    dr = ((pi + t // 2) % t - t // 2).astype(float)
    dc = ((pj + t // 2) % t - t // 2).astype(float)
    zero = np.zeros(dr.size)
    agree = consensus(dr, dc, zero, zero, tolerance_px=CONSENSUS_PX, height_tolerance_m=0.0)
    if agree.sum() < 2 and dr.size > 1:  # no two tiles agree: the sharpest peak
        agree = np.zeros(dr.size, bool)
        agree[int(np.argmax(flat.max(axis=1)))] = True
    return float(np.median(dr[agree])), float(np.median(dc[agree]))


def _nodes(ref_ok: np.ndarray, img_ok: np.ndarray, shift: tuple[int, int], half: int,
           margin: int, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes of the window, evenly spread, whose reference patch and warped search area
    (around the node plus ``shift``) have data."""
    from scipy.ndimage import binary_erosion

    a = binary_erosion(ref_ok, np.ones((2 * half + 3,) * 2, bool), border_value=0)
    b = binary_erosion(img_ok, np.ones((2 * (half + margin) + 1,) * 2, bool), border_value=0)
    # a node at p needs B around p + shift
    rows, cols = a.shape
    sr, sc = shift
    moved = np.zeros_like(b)
    dst = (slice(max(0, -sr), min(rows, rows - sr)), slice(max(0, -sc), min(cols, cols - sc)))
    src = (slice(max(0, sr), min(rows, rows + sr)), slice(max(0, sc), min(cols, cols + sc)))
    if dst[0].start < dst[0].stop and dst[1].start < dst[1].stop:
        moved[dst] = b[src]
    ok = a & moved
    count = int(ok.sum())
    if not count:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    spacing = max(half, int(math.ceil(math.sqrt(count / max_points))))
    r = np.arange(spacing // 2, rows, spacing)
    c = np.arange(spacing // 2, cols, spacing)
    rr, cc = (v.ravel() for v in np.meshgrid(r, c, indexing="ij"))
    keep = ok[rr, cc]
    rr, cc = rr[keep], cc[keep]
    if rr.size > max_points:
        pick = np.unique(np.linspace(0, rr.size - 1, max_points).round().astype(np.intp))
        rr, cc = rr[pick], cc[pick]
    return rr, cc


def _slope(dem: DemSource, lon: np.ndarray, lat: np.ndarray, step_m: float) -> np.ndarray:
    """``|grad h|`` by central differences over ``+- step_m`` (NaN where a neighbour has no
    height)."""
    dlon = step_m / (_DEG_M * np.cos(np.radians(lat)))
    dlat = step_m / _DEG_M
    he = dem.height(lon + dlon, lat)
    hw = dem.height(lon - dlon, lat)
    hn = dem.height(lon, lat + dlat)
    hs = dem.height(lon, lat - dlat)
    return np.hypot((he - hw) / (2 * step_m), (hn - hs) / (2 * step_m))


def _parallax(im: MatchImage, grid: Any, dem: DemSource, row: np.ndarray, col: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Where a DEM error moves the warped image: the shift of the ground the image's line of
    sight meets, per metre of height, reference pixels per metre (row, col) at the nodes
    (0 where it cannot be computed)."""
    lon, lat = grid.lonlat(row, col)
    h = dem.height(lon, lat)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ic, st = im.model.project_with_status(lon, lat, h)
        up, st2 = im.model.backproject_with_status(ic.row, ic.col, h + _PARALLAX_M)
    from geoblock import coords

    x, y = coords.transformer("EPSG:4326", grid.crs).transform(up.lon, up.lat)
    r2, c2 = grid.rowcol(np.asarray(x), np.asarray(y))
    er, ec = (r2 - row) / _PARALLAX_M, (c2 - col) / _PARALLAX_M
    ok = (np.asarray(st) == 0) & (np.asarray(st2) == 0) & np.isfinite(er) & np.isfinite(ec)
    return np.where(ok, er, 0.0), np.where(ok, ec, 0.0)


#: Height step of the parallax direction, metres.
_PARALLAX_M = 50.0


def match_one(im: MatchImage, ref: ReferenceOrtho, dem: DemSource, ce90: float,
              options: ReferenceOptions, say: Callable[[str], None], dem_sigma_m: float = 10.0
              ) -> tuple[ReferenceMatches, dict[str, np.ndarray]]:
    """Steps 1-6 of :mod:`geoblock.match.reference` for one image: its statistics, and the
    kept points' ``lon, lat, h, slope, row, col`` (the model's pixels as given)."""
    from geoblock.io.images import read_band
    from geoblock.match.geometry import ground_sample_distance
    from geoblock.match.pipeline import _accuracy_m
    from geoblock.match.refine import RefineStatus, refine_matches

    start = time.perf_counter()
    window, h_mean = _footprint(im, ref, dem)
    if window is None:
        return _empty(im, "no overlap", seconds=time.perf_counter() - start)
    r0, r1, c0, c1 = window
    if (r1 - r0) * (c1 - c0) > MAX_WINDOW_PIXELS:
        raise MatchError(
            f"{im.name}: covers {r1 - r0} x {c1 - c0} px of the reference {ref.path}, more "
            f"than {MAX_WINDOW_PIXELS} px; give a coarser reference (gdalwarp -tr) or split "
            "the image")
    rows, cols = (int(v) for v in im.image.shape)
    gsd = ground_sample_distance(im.model, (rows - 1) / 2, (cols - 1) / 2, h_mean)
    if not math.isfinite(gsd) or gsd <= 0:
        gsd = ref.gsd_m
    f = max(1, round(ref.gsd_m / gsd))
    grid = ref.grid(window)
    warped = _warp(im, grid, dem, f, options.image_band - 1)
    pix_ref = read_band(ref.image, window, ref.band - 1)
    ref_ok, img_ok = np.isfinite(pix_ref), np.isfinite(warped)
    common = dict(window=window, reduction=f, gsd_image_m=gsd)
    if not (ref_ok & img_ok).any():
        return _empty(im, "no overlap", seconds=time.perf_counter() - start, **common)
    accuracy = _accuracy_m(im.model)
    search = options.search_px
    if search is None:
        search = max(8.0, 3.0 * ((accuracy or 0.0) + ce90 / CE90_FACTOR) / ref.gsd_m)
    shift = _tile_shift(pix_ref, warped, max(TILE_PX, int(4 * search)))
    if shift is None:
        return _empty(im, "no shift", seconds=time.perf_counter() - start, **common)
    say(f"  {im.id}: reference rows {r0}-{r1}, cols {c0}-{c1}; image averaged {f}x{f} "
        f"({gsd:.3g} m pixels); tiles' shift {shift[0]:+.0f}, {shift[1]:+.0f} px")
    half, margin = options.half_px, options.refine_search_px + 3
    nr, nc = _nodes(ref_ok, img_ok, (round(shift[0]), round(shift[1])), half, margin,
                    options.max_points)
    n = nr.size
    status = np.full(n, "kept", dtype="<U11")
    d_row = np.full(n, np.nan)
    d_col = np.full(n, np.nan)
    score = np.full(n, np.nan)
    epi_r, epi_c = _parallax(im, grid, dem, nr.astype(float), nc.astype(float))
    if n:
        fr, fc = nr.astype(float), nc.astype(float)
        # starts along the parallax direction, 2 refine_search_px apart, out to three times
        # the DEM's accuracy: a DEM error moves the warped image along it, farther than the
        # correlation's search at a fine reference
        norm = np.hypot(epi_r, epi_c)
        ur = np.where(norm > 0, epi_r / np.where(norm > 0, norm, 1.0), 0.0)
        uc = np.where(norm > 0, epi_c / np.where(norm > 0, norm, 1.0), 0.0)
        reach = 3.0 * dem_sigma_m * norm
        step = 2.0 * options.refine_search_px
        m = int(math.ceil(float(reach.max()) / step)) if reach.size else 0
        first = np.full(n, 255, np.uint8)
        for t in sorted(np.arange(-m, m + 1) * step, key=abs):
            sel = np.flatnonzero(np.abs(t) <= reach + step / 2)
            if not sel.size:
                continue
            res = refine_matches(pix_ref, warped, fr[sel], fc[sel],
                                 fr[sel] + shift[0] + t * ur[sel],
                                 fc[sel] + shift[1] + t * uc[sel],
                                 np.broadcast_to(np.eye(2), (sel.size, 2, 2)), half_px=half,
                                 search_px=options.refine_search_px,
                                 min_score=options.min_score)
            if t == 0:
                first[sel] = res.status
            ok = res.status == RefineStatus.CONVERGED
            better = ok & ~(res.score <= score[sel])  # NaN score: not matched yet
            idx = sel[better]
            d_row[idx] = res.row[better] - fr[idx]
            d_col[idx] = res.col[better] - fc[idx]
            score[idx] = res.score[better]
        matched = np.isfinite(score)
        status[~matched & (first == RefineStatus.NO_DATA)] = "nodata"
        status[~matched & (first != RefineStatus.NO_DATA)] = "correlation"
    live = status == "kept"
    centre, scale = scale_of(warped.shape)
    shift_px = shift
    sigma_match = options.sigma_match_px or math.nan
    if live.sum() >= MIN_MATCHES:
        dr0, dc0 = np.nan_to_num(d_row), np.nan_to_num(d_col)
        agree = consensus(dr0[live], dc0[live], epi_r[live], epi_c[live], tolerance_px=1.0,
                          height_tolerance_m=3.0 * dem_sigma_m)
        begin = np.zeros(n, bool)
        begin[np.flatnonzero(live)[agree]] = True
        try:
            final = consistent(nr.astype(float), nc.astype(float), dr0, dc0, epi_r, epi_c,
                               begin, order=options.order, k=options.k, min_sigma_px=0.05,
                               sigma_px=0.5, sigma_h_m=dem_sigma_m,
                               max_sigma_h_m=2.0 * dem_sigma_m, centre=centre, scale=scale,
                               eligible=live)
            status[live & ~final.inlier] = "offset"
            kept = status == "kept"
            shift_px = final.bias.mean(nr[kept].astype(float), nc[kept].astype(float))
            if options.sigma_match_px is None:
                # across the parallax direction: the matching's own scatter (along it the
                # DEM's errors move the match, and sigma_h carries them)
                sigma_match = max(MAD_SCALE * float(np.median(np.abs(final.perp[kept]))),
                                  MIN_SIGMA_MATCH_PX)
        except MatchError:
            status[live] = "offset"
    else:
        status[live] = "offset"  # too few to test: none is trusted
    kept = np.flatnonzero(status == "kept")
    # --- control points: the node's ground; the match's position through the warp's mapping
    lon, lat = grid.lonlat(nr[kept].astype(float), nc[kept].astype(float))
    h = dem.height(lon, lat)
    q_lon, q_lat = grid.lonlat(nr[kept] + d_row[kept], nc[kept] + d_col[kept])
    q_h = dem.height(q_lon, q_lat)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ic, pstat = im.model.project_with_status(q_lon, q_lat, q_h)
    own, _, shared = reference_sigmas(ce90, sigma_match if math.isfinite(sigma_match) else 0.0,
                                      ref.gsd_m, 1.0, 0.0, options.local_accuracy_ce90_m)
    s_hor = math.hypot(own, shared)  # the whole horizontal uncertainty of the position
    step = max(s_hor, 0.5 * float(getattr(dem, "resolution_m", 0.0) or 0.0), 1.0)
    slope = _slope(dem, lon, lat, step) if kept.size else np.zeros(0)
    row = np.asarray(ic.row, float) + im.offset[0]
    col = np.asarray(ic.col, float) + im.offset[1]
    fine = (np.isfinite(h) & np.isfinite(q_h) & (np.asarray(pstat) == 0) & np.isfinite(row)
            & np.isfinite(col) & np.isfinite(slope))
    status[kept[~fine]] = "nodata"
    out = {"lon": lon[fine], "lat": lat[fine], "h": h[fine], "slope": slope[fine],
           "row": row[fine], "col": col[fine]}
    result = ReferenceMatches(
        im.id, "matched", window, f, gsd, nr + float(r0), nc + float(c0), d_row, d_col, score,
        status, (float(shift_px[0]), float(shift_px[1])), float(sigma_match),
        time.perf_counter() - start)
    return result, out
