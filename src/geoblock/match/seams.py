"""The misregistration of neighbouring orthos at their seam, measured on their pixels.

Two orthos on one north-up map grid (:func:`on_common_grid` places pixel-aligned orthos on the
union of their grids; :func:`overlapping_pairs` finds which overlap) are compared in their
overlap by robust least-squares matching (:func:`seam_shift`, with the solver of
:mod:`geoblock.match.lsm`): the translation ``d`` that makes ``b(x + d)`` look like ``a(x)``,
``x`` and ``d`` in pixels of the grid (row, col), i.e. where ortho ``b`` shows what ortho ``a``
shows at ``x``. The whole overlap is matched, and each of :data:`SEAM_SEGMENTS` segments along
the seam on its own (:class:`SeamShift`); the shift is given in metres east and north (the
grid's CRS units).

The method (Gruen's least-squares matching, translation plus a radiometric gain and offset):

* both orthos are smoothed by a Gaussian of :data:`SEAM_SMOOTHING_PX` (the gaps of each,
  outside the overlap, filled with the overlap's mean first: :func:`smoothed_overlap`), and
  the overlap's pixels closer than :data:`SEAM_MARGIN_PX` to the edge of either ortho are
  left out;
* ``a(x) = gain b(x + d) + offset`` is solved by Gauss-Newton from ``d = 0``, gain 1, offset 0,
  ``b`` interpolated by cubic splines and its gradient bilinearly; from the second iteration
  on each pixel has the Cauchy weight of its residual in units of :data:`SEAM_ROBUST_K`
  robust standard deviations, so that parts of the overlap that differ for other reasons than
  the shift (aliased texture, occlusions, clouds) do not pull it;
* iterations stop when the shift changes by at most :data:`SEAM_TOLERANCE_PX` (cap
  :data:`SEAM_MAX_ITERATIONS`).

Each match has an outcome (``SeamShift.status``, ``SeamShift.segment_status``):
``"converged"``; ``"not converged"`` (the iteration cap); ``"diverged"`` (the shift's length
beyond :data:`SEAM_MAX_SHIFT_PX`); ``"no texture"`` (the normal equations' column-equilibrated
condition number above :data:`SEAM_MAX_CONDITION`: a uniform overlap, or one whose texture is
a straight edge); ``"no data"`` (a sample without data: not expected, the gaps are filled
before smoothing); ``"too few pixels"`` (fewer than :data:`SEAM_MIN_PIXELS` to match).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import GridError, MosaicError, ShapeMismatchError
from geoblock.match.lsm import LsmStatus, least_squares_match
from geoblock.pixels import pixel_to_map

if TYPE_CHECKING:
    from affine import Affine

    from geoblock.typing import Float64Array, IndexArray, StrArray

__all__ = [
    "SEAM_MARGIN_PX",
    "SEAM_MAX_CONDITION",
    "SEAM_MAX_ITERATIONS",
    "SEAM_MAX_SHIFT_PX",
    "SEAM_MIN_PIXELS",
    "SEAM_ROBUST_K",
    "SEAM_SEGMENTS",
    "SEAM_SMOOTHING_PX",
    "SEAM_TOLERANCE_PX",
    "SeamOverlap",
    "SeamShift",
    "on_common_grid",
    "overlapping_pairs",
    "seam_shift",
    "smoothed_overlap",
]

#: Gaussian smoothing of both orthos before matching, pixels (sigma). Ground texture near the
#: pixel size (the simulated crop rows, e.g.) is sampled differently by each strip (aliasing:
#: a moire in the overlap's difference): those patterns differ between the strips and would
#: pull the match; smoothed, and down-weighted by the robust matching, they pull it less.
SEAM_SMOOTHING_PX = 3.0
#: Constant of the matcher's Cauchy weights, in robust standard deviations of the residuals.
SEAM_ROBUST_K = 2.0
#: Segments of an overlap along the seam, each matched on its own (the shift along the seam).
SEAM_SEGMENTS = 6
#: Fewest overlap pixels (after the margin is taken off) for a match, whole or segment.
SEAM_MIN_PIXELS = 150
#: Largest length of the shift the matcher follows, pixels: beyond it the match is
#: ``"diverged"``.
SEAM_MAX_SHIFT_PX = 2.0
#: Converged when no component of the shift changes by more than this in an iteration,
#: pixels.
SEAM_TOLERANCE_PX = 1e-3
#: Iteration cap of the matcher (Gauss-Newton).
SEAM_MAX_ITERATIONS = 20
#: Largest condition number of the matcher's column-equilibrated normal matrix (that of its
#: weighted Jacobian squared: 1e4 squared): above it the overlap has no texture to match
#: (``"no texture"``).
SEAM_MAX_CONDITION = 1e8
#: Overlap pixels closer than this to the edge of either ortho are not matched: the smoothing
#: (2 sigma), the largest shift and the cubic interpolation's support stay inside both orthos.
SEAM_MARGIN_PX = math.ceil(2 * SEAM_SMOOTHING_PX) + math.ceil(SEAM_MAX_SHIFT_PX) + 1

#: The outcome of a match as :class:`SeamShift` writes it.
_STATUS = {LsmStatus.CONVERGED: "converged", LsmStatus.MAX_ITERATIONS: "not converged",
           LsmStatus.DIVERGED: "diverged", LsmStatus.NO_TEXTURE: "no texture",
           LsmStatus.NO_DATA: "no data"}
_TOO_FEW = "too few pixels"


def _json(value: float) -> float | None:
    """JSON-safe float (None for NaN and infinities)."""
    value = float(value)
    return value if math.isfinite(value) else None


@dataclass(frozen=True, eq=False)
class SeamShift:
    """The shift between two neighbouring orthos in their overlap, measured on the images
    (:func:`seam_shift`; the method and the outcomes: :mod:`geoblock.match.seams`).

    The shift ``d`` is where ortho ``b`` shows what ortho ``a`` shows: ``b(x + d)`` matches
    ``a(x)``. In metres it has the sign of an ICTP discrepancy
    (:class:`~geoblock.adjust.IctpDiscrepancies`: from ``b`` minus from ``a``): for two orthos
    made with erroneous models it is, in the overlap, ``b``'s model error minus ``a``'s, which
    the ICTP discrepancies sample at a few points.

    Attributes
    ----------
    images : (str, str)
        ``(a, b)``.
    e, n : float
        Shift over the whole overlap, metres along the map's x (east) and y (north); NaN
        unless ``status`` is ``"converged"``.
    pixels : int
        Overlap pixels matched (inside the margin :data:`SEAM_MARGIN_PX`).
    iterations : int
        Gauss-Newton iterations of the whole overlap's match (0: not matched).
    status : str
        ``"converged"``, ``"not converged"`` (iteration cap), ``"diverged"`` (beyond
        :data:`SEAM_MAX_SHIFT_PX`), ``"no texture"``, ``"no data"`` or ``"too few pixels"``.
    segment_x, segment_y : ndarray, (K,)
        Centre of each segment along the seam (the mean of its pixels' centres), map
        coordinates (the grid's CRS units, metres); ``K`` is :data:`SEAM_SEGMENTS`, or 0
        when the whole overlap has too few pixels.
    segment_e, segment_n : ndarray, (K,)
        Each segment's shift, metres east and north (NaN where it did not converge).
    segment_status : ndarray of str, (K,)
        Each segment's outcome, as ``status``.
    """

    images: tuple[str, str]
    e: float
    n: float
    pixels: int
    iterations: int
    status: str
    segment_x: Float64Array
    segment_y: Float64Array
    segment_e: Float64Array
    segment_n: Float64Array
    segment_status: StrArray

    @property
    def shift(self) -> float:
        """Length of the whole-overlap shift, metres."""
        return math.hypot(self.e, self.n)

    @property
    def segment_rms(self) -> float:
        """RMS of the segments' shift lengths, metres (NaN when no segment converged): the
        misregistration along the seam, its variation included."""
        d2 = self.segment_e**2 + self.segment_n**2
        d2 = d2[np.isfinite(d2)]
        return float(np.sqrt(d2.mean())) if d2.size else math.nan

    def minus(self, reference: SeamShift) -> SeamShift:
        """This shift less ``reference``'s, over the whole overlap and segment by segment.

        With ``reference`` measured between orthos of the same images that line up (made
        with the TRUE models, in simulation), what the matching finds in the images' content
        alone (:func:`seam_shift` on aliased texture, e.g.) cancels to first order: the
        difference is the misregistration the models cause. A value is NaN unless both
        converged; the status is this one's when the reference converged, else the
        reference's (segments alike); pixels and iterations are this one's.

        Raises
        ------
        ShapeMismatchError
            The two have different numbers of segments (one has none: too few pixels).
        """
        if self.segment_e.shape != reference.segment_e.shape:
            raise ShapeMismatchError(
                f"SeamShift.minus: {self.images[0]} & {self.images[1]} has "
                f"{self.segment_e.size} segments, the reference {reference.segment_e.size}")
        ok = reference.segment_status == "converged"
        return SeamShift(
            self.images, self.e - reference.e, self.n - reference.n, self.pixels,
            self.iterations, self.status if reference.status == "converged"
            else reference.status, self.segment_x, self.segment_y,
            self.segment_e - reference.segment_e, self.segment_n - reference.segment_n,
            np.where(ok, self.segment_status, reference.segment_status))

    def as_dict(self) -> dict[str, Any]:
        """JSON-safe (NaN as None): the fields, ``shift``, ``segment_rms`` and a list of
        segments (``x, y, e, n, status``)."""
        return {"images": list(self.images), "e": _json(self.e), "n": _json(self.n),
                "shift": _json(self.shift), "segment_rms": _json(self.segment_rms),
                "pixels": self.pixels, "iterations": self.iterations, "status": self.status,
                "segments": [{"x": _json(x), "y": _json(y), "e": _json(e), "n": _json(n),
                              "status": str(s)}
                             for x, y, e, n, s in zip(self.segment_x, self.segment_y,
                                                      self.segment_e, self.segment_n,
                                                      self.segment_status, strict=True)]}


@dataclass(frozen=True, eq=False)
class SeamOverlap:
    """The overlap of two orthos on one grid, cropped to its bounding box (plus a margin), as
    the seam matcher sees it (:func:`smoothed_overlap`).

    Attributes
    ----------
    a, b : ndarray of float64, (R, C)
        The two orthos on the crop, smoothed by a Gaussian of :data:`SEAM_SMOOTHING_PX`
        pixels (each one's gaps filled with its mean over the overlap first).
    core : ndarray of bool, (R, C)
        The overlap's pixels farther than the margin from the edge of either ortho.
    origin : (int, int)
        The crop's first pixel ``(row, col)`` on the grid.
    """

    a: Float64Array
    b: Float64Array
    core: np.ndarray
    origin: tuple[int, int]


def smoothed_overlap(a: np.ndarray, b: np.ndarray, margin: int) -> SeamOverlap | None:
    """The overlap of two orthos on one grid, smoothed, and its pixels ``margin`` inside
    (:class:`SeamOverlap`); None when they have no pixel in common.

    Parameters
    ----------
    a, b : ndarray of float, (R, C)
        The two orthos on one grid, NaN where each has no pixel.
    margin : int
        Pixels: the crop extends this far beyond the overlap's bounding box (within the
        grid), and ``core`` keeps the overlap's pixels whose distance to the nearest pixel
        outside it (the grid's edge counting as outside) exceeds it.
    """
    from scipy import ndimage

    valid = np.isfinite(a) & np.isfinite(b)
    if not valid.any():
        return None
    rows, cols = np.nonzero(valid)
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, a.shape[0])
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, a.shape[1])
    crop = valid[r0:r1, c0:c1]
    smooth = []
    for image in (a[r0:r1, c0:c1].astype(np.float64), b[r0:r1, c0:c1].astype(np.float64)):
        filled = np.where(crop, image, np.mean(image[crop]))
        smooth.append(ndimage.gaussian_filter(filled, SEAM_SMOOTHING_PX))
    # distance to the nearest pixel outside the overlap, the array's edge counting as outside
    distance = ndimage.distance_transform_edt(np.pad(crop, 1))[1:-1, 1:-1]
    return SeamOverlap(smooth[0], smooth[1], distance > margin, (int(r0), int(c0)))


def _spline(b: Float64Array) -> tuple[Float64Array, Float64Array, Float64Array]:
    """Cubic-spline coefficients of ``b`` and its gradient along rows and columns."""
    from scipy import ndimage

    grad_row, grad_col = (np.asarray(g, np.float64) for g in np.gradient(b))
    return ndimage.spline_filter(b, order=3), grad_row, grad_col


def _match(a: Float64Array, b: tuple[Float64Array, Float64Array, Float64Array],
           rows: IndexArray, cols: IndexArray) -> tuple[float, float, int, str]:
    """Robust least-squares matching of ``b`` (:func:`_spline`) onto ``a`` at the pixels
    ``(rows, cols)`` (module docstring): ``d_row, d_col`` (pixels, NaN unless converged), the
    iterations and the outcome."""
    from scipy import ndimage

    if rows.size < SEAM_MIN_PIXELS:
        return math.nan, math.nan, 0, _TOO_FEW
    spline, grad_row, grad_col = b

    def sample(index: IndexArray, shift: Float64Array
               ) -> tuple[Float64Array, Float64Array, Float64Array]:
        """One patch: cubic-spline values and bilinear gradients at the pixels + ``shift``."""
        at = np.stack([rows + shift[0, 0], cols + shift[0, 1]])
        values = ndimage.map_coordinates(spline, at, order=3, prefilter=False, mode="nearest")
        gr = ndimage.map_coordinates(grad_row, at, order=1, mode="nearest")
        gc = ndimage.map_coordinates(grad_col, at, order=1, mode="nearest")
        return values[None], gr[None], gc[None]

    solution = least_squares_match(
        a[rows, cols][None], sample, np.zeros((1, 2)), robust_k=SEAM_ROBUST_K,
        radiometry="identity", max_iterations=SEAM_MAX_ITERATIONS,
        tolerance_px=SEAM_TOLERANCE_PX, max_shift_px=SEAM_MAX_SHIFT_PX,
        max_condition=SEAM_MAX_CONDITION)
    status = LsmStatus(solution.status[0])
    d_row, d_col = solution.shift[0] if status == LsmStatus.CONVERGED else (math.nan, math.nan)
    return float(d_row), float(d_col), int(solution.iterations[0]), _STATUS[status]


def seam_shift(a: np.ndarray, b: np.ndarray, transform: Affine,
               images: tuple[str, str] = ("a", "b")) -> SeamShift:
    """The shift between two orthos in their overlap, measured on the images (:class:`SeamShift`;
    the method: :mod:`geoblock.match.seams`).

    Parameters
    ----------
    a, b : ndarray of float, (R, C)
        The two orthos on one north-up map grid, NaN where each has no pixel.
    transform : affine.Affine
        The grid's geotransform (corner-based, rasterio order; pixel ``(row, col)`` has its
        centre at ``transform * (col + 0.5, row + 0.5)``); north-up: no rotation, x growing
        with the column and y decreasing with the row.
    images : (str, str)
        Their names.

    Returns
    -------
    SeamShift
        Status ``"too few pixels"`` (NaN shifts, no segment) when the orthos overlap by
        fewer than :data:`SEAM_MIN_PIXELS` pixels inside the margin.

    Raises
    ------
    ShapeMismatchError
        ``a`` and ``b`` are not 2-D arrays of one shape.
    GridError
        ``transform`` is not north-up.
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.ndim != 2 or a.shape != b.shape:
        raise ShapeMismatchError(f"seam_shift: the orthos of {images[0]} and {images[1]} are "
                                 f"not on one grid (shapes {a.shape} and {b.shape})")
    if transform.b != 0 or transform.d != 0 or not (transform.a > 0 and transform.e < 0):
        raise GridError(f"seam_shift: the grid of {images[0]} and {images[1]} must be north-up "
                        f"(transform a > 0, e < 0, no rotation), got {tuple(transform)[:6]}",
                        "transform")
    empty = np.zeros(0)
    found = smoothed_overlap(a, b, SEAM_MARGIN_PX)
    rows = cols = np.zeros(0, np.intp)
    if found is not None:
        rows, cols = np.nonzero(found.core)
    if found is None or rows.size < SEAM_MIN_PIXELS:
        return SeamShift(images, math.nan, math.nan, int(rows.size), 0, _TOO_FEW,
                         empty, empty, empty, empty, np.zeros(0, str))
    b_spline = _spline(found.b)
    dr, dc, iterations, status = _match(found.a, b_spline, rows, cols)
    # segments along the seam: the overlap's principal axis cut into equal lengths
    centred = np.column_stack([rows, cols]).astype(np.float64)
    centred -= centred.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    along = centred @ axis
    edges = np.linspace(along.min(), along.max(), SEAM_SEGMENTS + 1)
    segment = np.clip(np.searchsorted(edges, along, side="right") - 1, 0, SEAM_SEGMENTS - 1)
    seg = np.full((SEAM_SEGMENTS, 4), np.nan)  # centre row, col, d_row, d_col
    seg_status = np.empty(SEAM_SEGMENTS, dtype="<U14")
    r0, c0 = found.origin
    for k in range(SEAM_SEGMENTS):  # a few segments, each vectorised over its pixels
        mine = segment == k
        sr, sc = rows[mine], cols[mine]
        seg[k, :2] = (sr.mean() + r0, sc.mean() + c0) if sr.size else (np.nan, np.nan)
        *seg[k, 2:], _, seg_status[k] = _match(found.a, b_spline, sr, sc)
    res_x, res_y = transform.a, -transform.e  # metres per column (east), per row (south)
    x, y = pixel_to_map(transform, seg[:, 0], seg[:, 1])
    return SeamShift(images, dc * res_x, -dr * res_y, int(rows.size), iterations, status,
                     x, y, seg[:, 3] * res_x, -seg[:, 2] * res_y, seg_status)


def on_common_grid(bands: Mapping[str, tuple[np.ndarray, Affine]],
                   ) -> tuple[dict[str, np.ndarray], Affine]:
    """Orthos placed on the union of their grids, for :func:`seam_shift`.

    Parameters
    ----------
    bands : mapping of str to (ndarray, affine.Affine)
        Per image: a band ``(R_i, C_i)`` (NaN where no pixel) and its grid's geotransform.
        The grids must be pixel-aligned: one north-up resolution, origins whole pixels
        apart (as :meth:`~geoblock.ortho.OutputGrid.for_model` snaps them).

    Returns
    -------
    grids : dict of str to ndarray of float32, (R, C)
        Each band on the union grid, NaN outside it (float32: the union of a block's strips
        is large; :func:`seam_shift` computes in float64 on the overlap's crop).
    transform : affine.Affine
        The union grid's geotransform.

    Raises
    ------
    MosaicError
        No band, or grids of different resolutions, rotated, or not pixel-aligned (the
        message names the image).
    """
    from affine import Affine

    if not bands:
        raise MosaicError("on_common_grid: no ortho given")
    first = next(iter(bands.values()))[1]
    res_x, res_y = first.a, first.e  # res_y < 0: north-up
    for image_id, (band, t) in bands.items():
        same = math.isclose(t.a, res_x, rel_tol=1e-9) and math.isclose(t.e, res_y, rel_tol=1e-9)
        if np.ndim(band) != 2 or t.b != 0 or t.d != 0 or not same or not res_x > 0 > res_y:
            raise MosaicError(f"on_common_grid: the ortho of {image_id} is not on a north-up "
                              f"grid of the first one's resolution ({res_x}, {res_y}): "
                              f"transform {tuple(t)[:6]}, shape {np.shape(band)}")
        col, row = (t.c - first.c) / res_x, (t.f - first.f) / res_y
        if abs(col - round(col)) > 1e-6 or abs(row - round(row)) > 1e-6:
            raise MosaicError(f"on_common_grid: the ortho of {image_id} is not pixel-aligned "
                              f"with the first one (offset {row:.6f}, {col:.6f} px)")
    x0 = min(t.c for _, t in bands.values())
    y0 = max(t.f for _, t in bands.values())
    offsets = {image_id: (round((t.f - y0) / res_y), round((t.c - x0) / res_x))
               for image_id, (_, t) in bands.items()}
    rows = max(offsets[i][0] + band.shape[0] for i, (band, _) in bands.items())
    cols = max(offsets[i][1] + band.shape[1] for i, (band, _) in bands.items())
    grids: dict[str, np.ndarray] = {}
    for image_id, (band, _) in bands.items():
        r0, c0 = offsets[image_id]
        full = np.full((rows, cols), np.nan, dtype=np.float32)  # float64 on the crops only
        full[r0:r0 + band.shape[0], c0:c0 + band.shape[1]] = band
        grids[image_id] = full
    return grids, Affine(res_x, 0.0, x0, 0.0, res_y, y0)


def overlapping_pairs(grids: Mapping[str, np.ndarray],
                      min_pixels: int = SEAM_MIN_PIXELS) -> list[tuple[str, str]]:
    """Pairs of orthos on one grid (in the mapping's order) whose valid (finite) pixels
    overlap by at least ``min_pixels``."""
    ids = list(grids)
    valid = {i: np.isfinite(g) for i, g in grids.items()}
    return [(a, b) for k, a in enumerate(ids) for b in ids[k + 1:]
            if np.count_nonzero(valid[a] & valid[b]) >= min_pixels]
