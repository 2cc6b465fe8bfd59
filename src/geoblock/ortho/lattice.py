"""Source-image coordinates of output pixels: the indirect method on a refined (E, N, h) lattice.

For every output pixel centre, :func:`source_coordinates` gives the image ``(row, col)`` that
the orthorectifier resamples: pixel centre -> map ``(E, N)`` -> ``(lon, lat)`` -> DEM height
``h`` (metres above the ellipsoid) -> ``model.project(lon, lat, h)`` (Chen & Lee's indirect
method). Projecting every pixel exactly is expensive (pushbroom models iterate), so the exact
model is evaluated on a coarse lattice and interpolated:

* **Blocks.** The full output grid is cut into square blocks of ``block_px`` (a power of two)
  pixels, anchored at the grid origin. Every decision (lattice spacing, height levels, check
  points) is taken per block from the block's global indices alone, so a pixel gets the same
  value whatever the chunk it is computed in: output is identical for any chunking.
* **Nodes.** In a block, lattice nodes sit on the pixel centres whose global indices are
  multiples of the spacing ``s`` (a power of two, ``min(block_px / 4, 64)`` at first), nodes ``0 ..
  block_px / s`` inclusive along each axis. At each node the exact model is evaluated at
  ``2 m + 1`` ellipsoidal heights evenly spread over the block's DEM height range
  (``dem.height_range`` of the block's lon/lat box, padded).
* **Interpolation.** ``lon, lat`` of a pixel are bilinear in the nodes' (the DEM is then
  sampled there); ``row, col`` are bilinear in the node's ``(E, N)`` at each height level and
  piecewise quadratic (Lagrange on three consecutive levels) in ``h``.
* **Refinement.** ``check_points`` pixels of the block, drawn from a generator seeded with
  ``(seed, block row, block col)``, are projected exactly and compared with the lattice. While
  the largest error exceeds ``safety * tolerance_px`` the spacing is halved (and the number of
  height pairs doubled when the height interpolation alone exceeds a quarter of it). A block
  that still fails at spacing 1 is projected exactly.
* **Exact fallback.** Pixels whose interpolated coordinates are NaN although they have a DEM
  height (a node outside the model's domain) are projected exactly. ``tolerance_px == 0``
  projects every pixel exactly, block by block (a block is one model call whatever the
  chunking: iterative models may give last-bit differences between batches).

Only the :class:`~geoblock.models.SensorModel` protocol (``project_with_status``) and the
:class:`~geoblock.dem.DemSource` protocol (``height_with_status``, ``height_range``) are used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numba
import numpy as np

from geoblock import coords
from geoblock.ortho import _fused
from geoblock.ortho._fused import _cell, _column_cells, _quadratic_weights, _row_lerp
from geoblock.pixels import PIXEL_CENTRE, pixel_to_map
from geoblock.typing import ArrayLike

if TYPE_CHECKING:
    from affine import Affine
    from pyproj import CRS

    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel
    from geoblock.ortho.grid import OutputGrid

__all__ = ["LatticeInfo", "source_coordinates"]

#: Default side of the lattice blocks, output pixels (a power of two). A block's decision
#: (check points, node projections) is a fixed cost: 1024-pixel blocks amortise it over 16
#: times more pixels than 256-pixel ones (measured: 19 -> 23 Mpix/s on one core).
BLOCK_PX = 1024
#: First lattice spacing tried, output pixels (at most a quarter of the block).
FIRST_SPACING_PX = 64
#: Output rows interpolated and sampled together (the intermediates stay in the CPU cache).
STRIP_ROWS = 64
#: The checked error must be below ``SAFETY * tolerance_px`` (random checks see a sample).
SAFETY = 0.5
#: Largest number of quadratic height pairs (``2 m + 1`` levels) per block.
MAX_HEIGHT_PAIRS = 16


@dataclass
class LatticeInfo:
    """Diagnostics of one :func:`source_coordinates` call (pass ``info=LatticeInfo()``).

    Attributes
    ----------
    spacing : dict
        ``(block_row, block_col) -> (spacing_px, height_pairs)``; spacing 0 = projected exactly.
    check_error_px : dict
        ``(block_row, block_col) -> `` largest check-point error of the accepted lattice, px.
    exact_points : int
        Model evaluations at lattice nodes, check points and fallbacks.
    """

    spacing: dict[tuple[int, int], tuple[int, int]] = field(default_factory=dict)
    check_error_px: dict[tuple[int, int], float] = field(default_factory=dict)
    exact_points: int = 0


#: a block's lattice nodes: lon, lat (nr, nc) and image row, col (levels, nr, nc)
_Nodes = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


# ---------------------------------------------------------------------- numba kernels
@numba.njit(inline="always")
def _lerp2(nodes: np.ndarray, kr: int, kc: int, tr: float,
           tc: float) -> float:  # pragma: no cover - compiled
    """Bilinear in a cell: along rows first (as the row kernels precompute), then columns."""
    a = nodes[kr, kc] + tr * (nodes[kr + 1, kc] - nodes[kr, kc])
    b = nodes[kr, kc + 1] + tr * (nodes[kr + 1, kc + 1] - nodes[kr, kc + 1])
    return a + tc * (b - a)


@numba.njit(inline="always")
def _image_point(rn: np.ndarray, cn: np.ndarray, hh: float, kr: int, kc: int, tr: float,
                 tc: float, h0: float, dh: float,
                 pairs: int) -> tuple[float, float]:  # pragma: no cover - compiled
    """Image (row, col) at one pixel: bilinear in the nodes, quadratic in ``hh`` between
    levels ``h0 + k dh``; NaN for a NaN height."""
    if not np.isfinite(hh):
        return np.nan, np.nan
    lev, w0, w1, w2 = _quadratic_weights(hh, h0, dh, pairs)
    vr = w0 * _lerp2(rn[lev], kr, kc, tr, tc)
    vc = w0 * _lerp2(cn[lev], kr, kc, tr, tc)
    vr += w1 * _lerp2(rn[lev + 1], kr, kc, tr, tc)
    vc += w1 * _lerp2(cn[lev + 1], kr, kc, tr, tc)
    vr += w2 * _lerp2(rn[lev + 2], kr, kc, tr, tc)
    vc += w2 * _lerp2(cn[lev + 2], kr, kc, tr, tc)
    return vr, vc


@numba.njit(nogil=True, cache=True)
def _bilinear_into(nodes: np.ndarray, r_off: int, c_off: int, s: int,
                   out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out`` (nrows, ncols, any layout): bilinear interpolation of ``nodes`` (nr, nc) at
    block pixels ``r_off + i``, ``c_off + j`` (nodes at multiples of ``s``); bit-identical
    to :func:`_lerp2` per pixel."""
    nrows, ncols = out.shape
    inv = 1.0 / s
    line = np.empty(nodes.shape[1])
    kcs, tcs = _column_cells(c_off, ncols, s, nodes.shape[1])
    for i in range(nrows):
        kr, tr = _cell(r_off + i, s, inv, nodes.shape[0])
        _row_lerp(nodes, kr, tr, line)
        for j in range(ncols):
            kc = kcs[j]
            a = line[kc]
            out[i, j] = a + tcs[j] * (line[kc + 1] - a)


@numba.njit(nogil=True, cache=True)
def _bilinear(nodes: np.ndarray, r_off: int, c_off: int, nrows: int, ncols: int,
              s: int) -> np.ndarray:  # pragma: no cover - compiled
    """:func:`_bilinear_into` a new (nrows, ncols) array."""
    out = np.empty((nrows, ncols))
    _bilinear_into(nodes, r_off, c_off, s, out)
    return out


@numba.njit(nogil=True, cache=True)
def _interp_image_into(rn: np.ndarray, cn: np.ndarray, h: np.ndarray, r_off: int, c_off: int,
                       s: int, h0: float, dh: float, pairs: int, row: np.ndarray,
                       col: np.ndarray) -> int:  # pragma: no cover - compiled
    """Image ``row, col`` (nrows, ncols, any layout) of block pixels from node values
    ``rn, cn`` (levels, nr, nc): bilinear in the nodes, quadratic in ``h`` between levels
    ``h0 + k dh``; NaN where ``h`` is NaN. Bit-identical to :func:`_image_point` per pixel
    (the row step of the bilinear interpolation is done once per output row). Returns the
    number of pixels with a finite height but a non-finite result (a node outside the
    model's domain)."""
    nrows, ncols = h.shape
    nlev, nr, nc = rn.shape
    inv = 1.0 / s
    lr = np.empty((nlev, nc))
    lc = np.empty((nlev, nc))
    miss = 0
    kcs, tcs = _column_cells(c_off, ncols, s, nc)
    for i in range(nrows):
        kr, tr = _cell(r_off + i, s, inv, nr)
        for m in range(nlev):
            _row_lerp(rn[m], kr, tr, lr[m])
            _row_lerp(cn[m], kr, tr, lc[m])
        for j in range(ncols):
            hh = h[i, j]
            if not np.isfinite(hh):
                row[i, j] = np.nan
                col[i, j] = np.nan
                continue
            kc = kcs[j]
            tc = tcs[j]
            lev, w0, w1, w2 = _quadratic_weights(hh, h0, dh, pairs)
            a = lr[lev, kc]
            vr = w0 * (a + tc * (lr[lev, kc + 1] - a))
            a = lc[lev, kc]
            vc = w0 * (a + tc * (lc[lev, kc + 1] - a))
            a = lr[lev + 1, kc]
            vr += w1 * (a + tc * (lr[lev + 1, kc + 1] - a))
            a = lc[lev + 1, kc]
            vc += w1 * (a + tc * (lc[lev + 1, kc + 1] - a))
            a = lr[lev + 2, kc]
            vr += w2 * (a + tc * (lr[lev + 2, kc + 1] - a))
            a = lc[lev + 2, kc]
            vc += w2 * (a + tc * (lc[lev + 2, kc + 1] - a))
            row[i, j] = vr
            col[i, j] = vc
            if not (np.isfinite(vr) and np.isfinite(vc)):
                miss += 1
    return miss


@numba.njit(nogil=True, cache=True)
def _interp_image(rn: np.ndarray, cn: np.ndarray, h: np.ndarray, r_off: int, c_off: int,
                  s: int, h0: float, dh: float,
                  pairs: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """:func:`_interp_image_into` new (nrows, ncols) arrays ``row, col``."""
    row = np.empty(h.shape)
    col = np.empty(h.shape)
    _interp_image_into(rn, cn, h, r_off, c_off, s, h0, dh, pairs, row, col)
    return row, col


@numba.njit(nogil=True, cache=True)
def _bilinear_points(nodes: np.ndarray, pr: np.ndarray, pc: np.ndarray,
                     s: int) -> np.ndarray:  # pragma: no cover - compiled
    """:func:`_bilinear` at scattered block pixels ``(pr[k], pc[k])`` (1-D ints)."""
    out = np.empty(pr.size)
    inv = 1.0 / s
    for k in range(pr.size):
        kr, tr = _cell(pr[k], s, inv, nodes.shape[0])
        kc, tc = _cell(pc[k], s, inv, nodes.shape[1])
        out[k] = _lerp2(nodes, kr, kc, tr, tc)
    return out


@numba.njit(nogil=True, cache=True)
def _interp_image_points(rn: np.ndarray, cn: np.ndarray, h: np.ndarray, pr: np.ndarray,
                         pc: np.ndarray, s: int, h0: float, dh: float,
                         pairs: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
    """:func:`_interp_image` at scattered block pixels ``(pr[k], pc[k])`` with heights
    ``h[k]`` (1-D)."""
    row = np.empty(pr.size)
    col = np.empty(pr.size)
    inv = 1.0 / s
    for k in range(pr.size):
        kr, tr = _cell(pr[k], s, inv, rn.shape[1])
        kc, tc = _cell(pc[k], s, inv, rn.shape[2])
        row[k], col[k] = _image_point(rn, cn, h[k], kr, kc, tr, tc, h0, dh, pairs)
    return row, col


# ---------------------------------------------------------------------- helpers
def _grid_parts(grid: OutputGrid) -> tuple[CRS, Affine, tuple[int, int]]:
    return grid.crs, grid.transform, (int(grid.shape[0]), int(grid.shape[1]))


def _slice_bounds(sl: slice | None, size: int) -> tuple[int, int]:
    if sl is None:
        return 0, size
    start, stop, step = sl.indices(size)
    if step != 1:
        raise ValueError("source_coordinates: window slices must have step 1")
    return start, max(start, stop)


class _Context:
    """What every block of one call shares: the model, DEM, grid and transformer."""

    def __init__(self, model: SensorModel, dem: DemSource, crs: CRS, transform: Affine,
                 shape: tuple[int, int], info: LatticeInfo | None) -> None:
        self.model = model
        self.dem = dem
        self.transform = transform
        self.shape = shape
        self.to_lonlat = coords.transformer(crs, "EPSG:4326")
        self.info = info

    def lonlat(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact lon/lat (degrees) of global pixel indices (pixel centres)."""
        x, y = pixel_to_map(self.transform, rows, cols)
        lon, lat = self.to_lonlat.transform(x, y)
        return np.asarray(lon, dtype=np.float64), np.asarray(lat, dtype=np.float64)

    def project(self, lon: ArrayLike, lat: ArrayLike,
                h: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        (row, col), _ = self.model.project_with_status(lon, lat, h)
        if self.info is not None:
            self.info.exact_points += int(np.size(row))
        return np.asarray(row, dtype=np.float64), np.asarray(col, dtype=np.float64)

    def height(self, lon: ArrayLike, lat: ArrayLike) -> np.ndarray:
        return np.asarray(self.dem.height(lon, lat), dtype=np.float64)

    def exact(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact image coordinates of global pixel indices (any shape)."""
        lon, lat = self.lonlat(rows, cols)
        h = self.height(lon, lat)
        return self.project(lon, lat, h)


class _Block:
    """One lattice block: its spacing decision and its node values."""

    def __init__(self, ctx: _Context, bi: int, bj: int, size: int, tol: float,
                 n_check: int, seed: int) -> None:
        self.ctx = ctx
        self.bi, self.bj, self.size = bi, bj, size
        rows, cols = ctx.shape
        self.r0, self.c0 = bi * size, bj * size
        self.nrows = min(size, rows - self.r0)
        self.ncols = min(size, cols - self.c0)
        self.spacing = 0  # 0: exact
        self.pairs = 1
        self._with_fallback: tuple[np.ndarray, np.ndarray] | None = None
        self.nodes: tuple[np.ndarray, ...] | None = None
        if tol == 0:
            self.h_range: tuple[float, float] | None = (0.0, 0.0)
            return
        self.h_range = self._height_range()
        if self.h_range is None:
            return  # no DEM height anywhere in the block: every pixel invalid
        self._decide(tol, n_check, seed)

    # -- heights
    def _height_range(self) -> tuple[float, float] | None:
        """Padded (lo, hi) ellipsoidal heights over the block's lon/lat box, or None."""
        ctx = self.ctx
        t = np.linspace(-0.5, 1.0, 7)  # block edges, a bit beyond
        # from the outer edge of the block's first pixel
        rr = self.r0 - PIXEL_CENTRE + t * (self.size + 0.5)
        cc = self.c0 - PIXEL_CENTRE + t * (self.size + 0.5)
        r_e = np.concatenate([rr, rr, np.full(7, rr[0]), np.full(7, rr[-1])])
        c_e = np.concatenate([np.full(7, cc[0]), np.full(7, cc[-1]), cc, cc])
        lon, lat = ctx.lonlat(r_e, c_e)
        if not (np.isfinite(lon).all() and np.isfinite(lat).all()):
            return (float(ctx.model.height_range[0]), float(ctx.model.height_range[1]))
        # one DEM post around the box: a DEM interpolates between posts outside it
        pad_lat = 1.5 * float(ctx.dem.resolution_m or 0.0) / 111_000.0
        pad_lon = pad_lat / max(math.cos(math.radians(float(np.abs(lat).max()))), 1e-6)
        bounds = (float(lon.min()) - pad_lon, max(float(lat.min()) - pad_lat, -90.0),
                  float(lon.max()) + pad_lon, min(float(lat.max()) + pad_lat, 90.0))
        lo, hi = ctx.dem.height_range(bounds)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return None
        pad = max(1.0, 0.05 * (hi - lo))
        return (float(lo) - pad, float(hi) + pad)

    def levels(self, pairs: int) -> np.ndarray:
        lo, hi = self.h_range  # type: ignore[misc]
        return np.linspace(lo, hi, 2 * pairs + 1)

    # -- nodes
    def _node_lonlat(self, s: int) -> tuple[np.ndarray, np.ndarray]:
        n = self.size // s + 1
        k = np.arange(n) * s
        rr, cc = np.meshgrid(self.r0 + k, self.c0 + k, indexing="ij")
        return self.ctx.lonlat(rr, cc)

    def _nodes(self, s: int, pairs: int,
               lonlat: tuple[np.ndarray, np.ndarray] | None = None) -> _Nodes:
        lon, lat = self._node_lonlat(s) if lonlat is None else lonlat
        lev = self.levels(pairs)
        nl = lev.size
        row, col = self.ctx.project(
            np.broadcast_to(lon, (nl,) + lon.shape), np.broadcast_to(lat, (nl,) + lat.shape),
            np.broadcast_to(lev[:, None, None], (nl,) + lon.shape),
        )
        return lon, lat, np.ascontiguousarray(row), np.ascontiguousarray(col)

    def _interpolate_points(self, nodes: _Nodes, s: int, pairs: int, pr: ArrayLike,
                            pc: ArrayLike) -> tuple[np.ndarray, ...]:
        """Lattice coordinates at block pixels (pr, pc) (1-D, block-local), the production
        path: interpolated lon/lat -> DEM -> lattice."""
        lon_n, lat_n, rn, cn = nodes
        pr = np.ascontiguousarray(pr, dtype=np.int64)
        pc = np.ascontiguousarray(pc, dtype=np.int64)
        lon = _bilinear_points(lon_n, pr, pc, s)
        lat = _bilinear_points(lat_n, pr, pc, s)
        h = self.ctx.height(lon, lat)
        lev = self.levels(pairs)
        dh = (lev[-1] - lev[0]) / (lev.size - 1)
        out_r, out_c = _interp_image_points(rn, cn, np.ascontiguousarray(h, dtype=np.float64),
                                            pr, pc, s, lev[0], dh, pairs)
        return out_r, out_c, lon, lat, h

    def _decide(self, tol: float, n_check: int, seed: int) -> None:
        ctx = self.ctx
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, self.bi, self.bj])
        pr = rng.integers(0, self.nrows, n_check)
        pc = rng.integers(0, self.ncols, n_check)
        ex_r, ex_c = ctx.exact(self.r0 + pr, self.c0 + pc)
        ok = np.isfinite(ex_r) & np.isfinite(ex_c)
        s = max(min(self.size // 4, FIRST_SPACING_PX), 1)
        pairs = 1
        while True:
            nodes = self._nodes(s, pairs)
            lr, lc, lon, lat, h = self._interpolate_points(nodes, s, pairs, pr, pc)
            err = np.hypot(lr - ex_r, lc - ex_c)[ok]
            # a finite exact value the lattice misses (NaN node) is refined too
            err = np.where(np.isfinite(err), err, np.inf)
            worst = float(err.max()) if err.size else 0.0
            if worst <= SAFETY * tol:
                self.spacing, self.pairs, self.nodes = s, pairs, nodes
                if ctx.info is not None:
                    ctx.info.spacing[(self.bi, self.bj)] = (s, pairs)
                    ctx.info.check_error_px[(self.bi, self.bj)] = worst
                return
            # the height interpolation alone, at the checks' own lon/lat and heights
            lev = self.levels(pairs)
            hr, hc = ctx.project(np.broadcast_to(lon, (lev.size, lon.size)),
                                 np.broadcast_to(lat, (lev.size, lat.size)),
                                 np.broadcast_to(lev[:, None], (lev.size, lon.size)))
            er, ec = ctx.project(lon, lat, h)
            qr, qc = _quadratic_in_h(hr, hc, h, lev, pairs)
            h_err = np.hypot(qr - er, qc - ec)
            h_err = h_err[np.isfinite(h_err)]
            h_worst = float(h_err.max()) if h_err.size else 0.0
            changed = False
            if h_worst > 0.25 * SAFETY * tol and pairs < MAX_HEIGHT_PAIRS:
                pairs *= 2
                changed = True
            if s > 1 and (not changed or worst > 2 * h_worst):
                s //= 2
                changed = True
            if not changed:
                break
        self.spacing, self.nodes = 0, None  # projected exactly
        if ctx.info is not None:
            ctx.info.spacing[(self.bi, self.bj)] = (0, 0)
            ctx.info.check_error_px[(self.bi, self.bj)] = 0.0

    # -- production
    def _exact_block(self) -> tuple[np.ndarray, np.ndarray]:
        """Exact coordinates of the whole block, in one model call (the same batch whatever
        the chunk, so that iterative models give the same bits)."""
        rr, cc = np.meshgrid(self.r0 + np.arange(self.nrows), self.c0 + np.arange(self.ncols),
                             indexing="ij")
        return self.ctx.exact(rr, cc)

    def _lattice(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int) -> tuple[np.ndarray, ...]:
        """Lattice coordinates, interpolated lon/lat and heights of block-local pixels."""
        s, pairs = self.spacing, self.pairs
        lon_n, lat_n, rn, cn = self.nodes  # type: ignore[misc]
        nr, nc = r_hi - r_lo, c_hi - c_lo
        lon = _bilinear(lon_n, r_lo, c_lo, nr, nc, s)
        lat = _bilinear(lat_n, r_lo, c_lo, nr, nc, s)
        h = self.ctx.height(lon, lat)
        lev = self.levels(pairs)
        dh = (lev[-1] - lev[0]) / (lev.size - 1)
        row, col = _interp_image(rn, cn, h, r_lo, c_lo, s, lev[0], dh, pairs)
        return row, col, lon, lat, h

    def lonlat_into(self, lon_w: np.ndarray, lat_w: np.ndarray, r_lo: int, r_hi: int,
                    c_lo: int, c_hi: int, dst_r: int, dst_c: int) -> None:
        """Interpolated lon/lat of block-local pixels into window arrays (lattice blocks)."""
        lon_n, lat_n, _, _ = self.nodes  # type: ignore[misc]
        nr, nc = r_hi - r_lo, c_hi - c_lo
        sl = (slice(dst_r, dst_r + nr), slice(dst_c, dst_c + nc))
        _bilinear_into(lon_n, r_lo, c_lo, self.spacing, lon_w[sl])
        _bilinear_into(lat_n, r_lo, c_lo, self.spacing, lat_w[sl])

    def fill_lattice(self, out_r: np.ndarray, out_c: np.ndarray, h: np.ndarray, r_lo: int,
                     r_hi: int, c_lo: int, c_hi: int, dst_r: int, dst_c: int) -> None:
        """:meth:`fill` for a lattice block whose pixels' DEM heights ``h`` (nr, nc) are
        already sampled (at the lon/lat of :meth:`lonlat_into`)."""
        nr, nc = r_hi - r_lo, c_hi - c_lo
        sl = (slice(dst_r, dst_r + nr), slice(dst_c, dst_c + nc))
        _, _, rn, cn = self.nodes  # type: ignore[misc]
        s, pairs = self.spacing, self.pairs
        lev = self.levels(pairs)
        dh = (lev[-1] - lev[0]) / (lev.size - 1)
        if _interp_image_into(rn, cn, h, r_lo, c_lo, s, lev[0], dh, pairs, out_r[sl],
                              out_c[sl]):
            # nodes outside the model's domain: the whole-block exact fallback, as fill does
            self.fill(out_r, out_c, r_lo, r_hi, c_lo, c_hi, dst_r, dst_c)

    def fill(self, out_r: np.ndarray, out_c: np.ndarray, r_lo: int, r_hi: int, c_lo: int,
             c_hi: int, dst_r: int, dst_c: int) -> None:
        """Write the coordinates of block-local pixels ``[r_lo, r_hi) x [c_lo, c_hi)`` into
        ``out_*[dst_r: ..., dst_c: ...]``."""
        nr, nc = r_hi - r_lo, c_hi - c_lo
        sl = (slice(dst_r, dst_r + nr), slice(dst_c, dst_c + nc))
        part = (slice(r_lo, r_hi), slice(c_lo, c_hi))
        if self.h_range is None:
            out_r[sl] = np.nan
            out_c[sl] = np.nan
            return
        if self.spacing == 0:
            row, col = self._exact_block()
            out_r[sl], out_c[sl] = row[part], col[part]
            return
        if self._with_fallback is None:
            row, col, lon, lat, h = self._lattice(r_lo, r_hi, c_lo, c_hi)
            miss = np.isfinite(h) & ~(np.isfinite(row) & np.isfinite(col))
            if not miss.any():
                out_r[sl], out_c[sl] = row, col
                return
            # nodes outside the model's domain: those pixels exactly, batched over the whole
            # block so that the batch (and so the bits) does not depend on the chunk; kept
            # for the block's other strips
            row, col, lon, lat, h = self._lattice(0, self.nrows, 0, self.ncols)
            miss = np.isfinite(h) & ~(np.isfinite(row) & np.isfinite(col))
            er, ec = self.ctx.project(lon[miss], lat[miss], h[miss])
            row[miss], col[miss] = er, ec
            self._with_fallback = (row, col)
        row, col = self._with_fallback
        out_r[sl], out_c[sl] = row[part], col[part]


def _fill_fused(block: _Block, dem_plan: _fused.DemPlan, part: tuple[int, int, int, int],
                dst_r: int, dst_c: int, out_r: np.ndarray, out_c: np.ndarray) -> bool:
    """A lattice block's pixels ``part`` (block-local rows a..b, cols c..d) through the fused
    pass, written at window pixel ``(dst_r, dst_c)``; False when the pass does not apply (the
    reference path then runs and overwrites whatever was written)."""
    a, b, c, d = part
    lon_n, lat_n, rn, cn = block.nodes  # type: ignore[misc]
    window = _fused.dem_window(dem_plan, lon_n, lat_n, block.nrows * block.ncols)
    if window is None:
        return False
    sl = (slice(dst_r, dst_r + b - a), slice(dst_c, dst_c + d - c))
    lev = block.levels(block.pairs)
    dh = (lev[-1] - lev[0]) / (lev.size - 1)
    done, miss = _fused.fill_block_rows(dem_plan, window, lon_n, lat_n, rn, cn, a, c,
                                        block.spacing, float(lev[0]), float(dh), block.pairs,
                                        out_r[sl], out_c[sl])
    if not done:
        return False
    if miss:  # nodes outside the model's domain: the whole-block exact fallback
        block.fill(out_r, out_c, a, b, c, d, dst_r, dst_c)
    return True


def _quadratic_in_h(vr: np.ndarray, vc: np.ndarray, h: np.ndarray, lev: np.ndarray,
                    pairs: int) -> tuple[np.ndarray, np.ndarray]:
    """Piecewise-quadratic interpolation in ``h`` of per-level values ``(levels, N)``."""
    dh = (lev[-1] - lev[0]) / (lev.size - 1)
    u = (h - lev[0]) / dh
    k = np.clip(np.floor(u * 0.5), 0, pairs - 1).astype(np.intp)
    t = u - 2.0 * k
    w = (0.5 * (t - 1) * (t - 2), -t * (t - 2), 0.5 * t * (t - 1))
    idx = np.arange(h.size)
    qr = sum(w[m] * vr[2 * k + m, idx] for m in range(3))
    qc = sum(w[m] * vc[2 * k + m, idx] for m in range(3))
    return qr, qc


# ---------------------------------------------------------------------- public
def source_coordinates(
    model: SensorModel,
    dem: DemSource,
    grid: OutputGrid,
    *,
    tolerance_px: float = 0.01,
    check_points: int = 16,
    seed: int = 0,
    window: tuple[slice, slice] | None = None,
    block_px: int = BLOCK_PX,
    info: LatticeInfo | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image coordinates of the output pixel centres of ``grid`` (or of a window of it).

    Parameters
    ----------
    model : SensorModel
        Anything with ``project_with_status(lon, lat, h)`` (ground -> image, pixel-centre
        convention) and ``height_range``.
    dem : DemSource
        Heights above the WGS84 ellipsoid (``height_with_status``, ``height_range``).
    grid : OutputGrid
        The output grid (``crs``, ``transform``, ``shape``). Pass the **full** grid and the
        chunk as ``window``: the lattice is anchored to ``grid``'s origin, so the values do not
        depend on the chunking. (A sub-grid passed alone is its own anchor.)
    tolerance_px : float
        Largest interpolation error accepted at the check points, image pixels (default
        0.01). ``0``: every pixel is projected exactly.
    check_points : int
        Pixels per lattice block compared with the exact model.
    seed : int
        Seed of the check points (with the block's global indices).
    window : (slice, slice), optional
        ``(rows, cols)`` of ``grid`` to compute (step 1); default the whole grid.
    block_px : int
        Side of the lattice blocks, output pixels; a power of two. Part of the result's
        definition: keep it fixed to compare runs.
    info : LatticeInfo, optional
        Filled with the spacing chosen per block and the check errors.

    Returns
    -------
    row, col : ndarray, (R, C) float64
        Source-image pixel-centre coordinates of the window's pixels; NaN where invalid.
    valid : ndarray, (R, C) bool
        Finite coordinates: a DEM height exists and the model projects the point.

    Raises
    ------
    ValueError
        ``block_px`` is not a power of two, ``tolerance_px`` is negative, a slice step is
        not 1.
    """
    if block_px < 1 or block_px & (block_px - 1):
        raise ValueError(f"source_coordinates: block_px must be a power of two, got {block_px}")
    if not tolerance_px >= 0:
        raise ValueError(f"source_coordinates: tolerance_px must be >= 0, got {tolerance_px}")
    crs, transform, shape = _grid_parts(grid)
    ctx = _Context(model, dem, crs, transform, shape, info)
    return _lattice_fields(ctx, tolerance_px=tolerance_px, check_points=check_points, seed=seed,
                          window=window, block_px=block_px)


def _lattice_fields(
    ctx: _Context,
    *,
    tolerance_px: float,
    check_points: int = 16,
    seed: int = 0,
    window: tuple[slice, slice] | None = None,
    block_px: int = BLOCK_PX,
    fused: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`source_coordinates` for any pair of smooth fields of ``(lon, lat, h)``.

    ``ctx.project(lon, lat, h) -> (a, b)`` gives the two fields (NaN where undefined); they
    are interpolated on the lattice and refined until ``hypot(da, db)`` at the check points is
    below ``SAFETY * tolerance_px`` (in the fields' units), exactly as the image coordinates
    are. The accuracy layer (:mod:`geoblock.ortho.accuracy`) passes a context whose fields are
    the logarithm of the predicted error (a relative tolerance) and 0.

    ``fused``: lattice blocks go through :mod:`geoblock.ortho._fused`'s one-pass kernel when
    the DEM allows it (bit-identical); False forces the reference path (separate lon/lat,
    DEM and interpolation passes over strips), for the tests that compare them.
    """
    shape = ctx.shape
    rs, cs = window if window is not None else (None, None)
    r0, r1 = _slice_bounds(rs, shape[0])
    c0, c1 = _slice_bounds(cs, shape[1])
    # every pixel is written below (by its block's fill or fill_lattice)
    out_r = np.empty((r1 - r0, c1 - c0))
    out_c = np.empty((r1 - r0, c1 - c0))
    if out_r.size == 0:
        return out_r, out_c, np.zeros(out_r.shape, bool)
    B = int(block_px)
    dem_plan = _fused.plan(ctx.dem) if fused and type(ctx).height is _Context.height else None
    # Per row of blocks: each block takes its decision; lattice blocks then go strip by strip
    # (STRIP_ROWS rows: the strip's lon/lat, heights and coordinates stay in the CPU cache),
    # interpolating their pixels' lon/lat into strip-wide arrays, the DEM sampled once per
    # strip (DEM heights are pointwise: batching does not change a bit), then each block
    # interpolating its image coordinates.
    for bi in range(r0 // B, (r1 - 1) // B + 1):
        lo_r, hi_r = max(r0, bi * B), min(r1, (bi + 1) * B)
        pending = []
        blank = []  # window columns of blocks without lattice: NaN lon/lat in the strips
        for bj in range(c0 // B, (c1 - 1) // B + 1):
            block = _Block(ctx, bi, bj, B, float(tolerance_px), int(check_points), seed)
            lo_c, hi_c = max(c0, bj * B), min(c1, (bj + 1) * B)
            part = (lo_r - bi * B, hi_r - bi * B, lo_c - bj * B, hi_c - bj * B)
            if block.h_range is not None and block.spacing > 0:
                pending.append((block, part))
            else:
                block.fill(out_r, out_c, *part, lo_r - r0, lo_c - c0)
                blank.append(slice(lo_c - c0, hi_c - c0))
        if not pending:
            continue
        if dem_plan is not None:  # the fused pass, block by block; the others below
            pending = [(block, part) for block, part in pending
                       if not _fill_fused(block, dem_plan, part, lo_r - r0,
                                          block.c0 + part[2] - c0, out_r, out_c)]
            if not pending:
                continue
            blank = [slice(0, c1 - c0)]  # lon/lat only where a pending block writes them
        for s_lo in range(lo_r, hi_r, STRIP_ROWS):
            s_hi = min(s_lo + STRIP_ROWS, hi_r)
            lon_s = np.empty((s_hi - s_lo, c1 - c0))
            lat_s = np.empty((s_hi - s_lo, c1 - c0))
            for cols in blank:
                lon_s[:, cols] = np.nan
                lat_s[:, cols] = np.nan
            a, b = s_lo - bi * B, s_hi - bi * B  # block-local rows of the strip
            for block, (_, _, c, d) in pending:
                block.lonlat_into(lon_s, lat_s, a, b, c, d, 0, block.c0 + c - c0)
            h_s = ctx.height(lon_s, lat_s)
            for block, (_, _, c, d) in pending:
                dst_c = block.c0 + c - c0
                h = np.ascontiguousarray(h_s[:, dst_c:dst_c + d - c])
                block.fill_lattice(out_r, out_c, h, a, b, c, d, s_lo - r0, dst_c)
    valid = np.isfinite(out_r)
    valid &= np.isfinite(out_c)
    if not valid.all():
        out_r[~valid] = np.nan
        out_c[~valid] = np.nan
    return out_r, out_c, valid
