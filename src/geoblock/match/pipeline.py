"""Tie points from images guided by their sensor models: :func:`match_images`, :func:`match_block`.

For every pair of images selected from their footprints on the DEM
(:func:`geoblock.match.select_pairs`; :func:`geoblock.match.geometry.overlap` gives the windows
each image is read in), as tasks on any dask scheduler (:mod:`geoblock.match.tasks`):

1. **keypoints** - SIFT, spread over each image's part of the overlaps
   (:func:`~geoblock.match.features.detect_keypoints`);
2. **prediction** - each keypoint of A on the DEM through A's model, projected into B through
   B's (:func:`~geoblock.match.geometry.predict`), with its epipolar direction;
3. **bias** - the strongest, well spread keypoints of A are matched to B's keypoints inside a
   wide window around the prediction (``search_px``, widened along the epipolar direction by
   three times the DEM's accuracy), with Lowe's ratio test; the constant offset most of them
   agree on (:func:`~geoblock.match.consistency.consensus`) starts the robust fit of the
   models' disagreement, a low-order image-space bias
   (:func:`~geoblock.match.consistency.consistent`);
4. **guided matching** - every keypoint of A is matched to B's keypoints inside a narrow
   window around its bias-corrected prediction, elongated along the epipolar direction by the
   height parallax the first fit measured; ratio test; one match per keypoint of B;
5. **sub-pixel refinement** - normalised cross-correlation of A's patch with B resampled in
   the models' local geometry, then least-squares matching
   (:func:`~geoblock.match.refine.refine_matches`);
6. **outlier test** - the refined matches against the bias: the epipolar test (across the
   epipolar direction: noise only) and the height test (along it: the height parallax),
   iterated to a fixed point (:mod:`geoblock.match.consistency`);
7. **tracks** - matches sharing a keypoint are one tie point; a point seen in more than two
   images gets one id. Each track's first image (in the order given) is its reference: its
   keypoint is measured as detected and the other images are refined against its patch.

Pixels in the results are those of each image's sensor model as given: for an image that is a
crop of the model's scene (a pixel-unit geotransform, ``crop_offset=``) the scene's pixels,
the ones ``geoblock adjust`` reads with the model file a block file names. The method and its
outlier test are explained in docs/user-guide/match.md.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError
from geoblock.match.consistency import consensus, consistent, scale_of, split_residuals
from geoblock.match.features import Keypoints
from geoblock.match.geometry import (
    Overlap,
    Prediction,
    ground_sample_distance,
    local_affine,
    overlap,
    predict,
)
from geoblock.match.pairs import PairGraph, select_pairs
from geoblock.match.refine import RefineStatus
from geoblock.match.results import REJECTIONS, PairMatches, TiePoints

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.io.images import OpenedImage
    from geoblock.models.protocol import SensorModel

__all__ = ["DEFAULT_SEARCH_PX", "MatchImage", "MatchOptions", "match_block", "match_images",
           "write_tie_points"]

Progress = Callable[[str], None]

#: Radius of the first pass' search window when the models do not state their accuracy,
#: pixels of B.
DEFAULT_SEARCH_PX = 60.0
#: Smallest first-pass radius, pixels.
MIN_SEARCH_PX = 10.0
#: Matches needed to estimate the bias between two images.
MIN_BIAS_MATCHES = 5


# ============================================================================== inputs
@dataclass(frozen=True)
class MatchOptions:
    """Options of :func:`match_images`.

    Attributes
    ----------
    max_keypoints : int
        SIFT keypoints kept per image, spread over cells of ``cell_px``.
    cell_px : int
        Side of the cells the keypoints are spread over, pixels.
    contrast_threshold : float
        SIFT's contrast threshold (OpenCV's default 0.04; lower finds more in flat areas).
    search_px : float or None
        Radius of the first pass' window around the prediction, pixels of B: how far the
        models may disagree. None: three times the combined location accuracy the models
        state (``location_accuracy_m``), at least 10 px, else :data:`DEFAULT_SEARCH_PX`.
    dem_sigma_m : float
        Accuracy of the DEM's heights (1 sigma, metres): the first pass' window extends
        three times this height parallax along the epipolar direction.
    ratio : float
        Lowe's ratio test: the best descriptor distance in the window must be below
        ``ratio`` times the second best.
    bias_keypoints : int
        Keypoints of A (the strongest of each cell) matched in the first pass.
    candidates : int
        Nearest keypoints of B examined per keypoint of A in the windows.
    order : {0, 1, 2}
        Order of the image-space bias polynomial (0: shift, 1: affine).
    k : float
        Rejection threshold of the epipolar and height tests, robust standard deviations.
    half_px : int
        Correlation patch half-size, pixels: ``(2 half_px + 1)^2`` patches.
    refine_search_px : int
        Largest correction of a keypoint's position by the correlation, pixels.
    min_score : float
        Smallest normalised cross-correlation kept.
    sigma_px : float or None
        The ``sigma`` written with each measurement, pixels; None: estimated per pair, the
        robust scale of the kept matches' residuals across the epipolar direction over
        sqrt(2) (both measurements of a match share it), at least 0.05 px.
    id_prefix : str
        Tie-point ids are ``<id_prefix><number>``, numbered in the order of their reference
        image and position (the same inputs give the same ids).
    min_overlap : float
        Pairs overlapping less than this share of the smaller footprint are not matched
        (:func:`geoblock.match.select_pairs`).
    max_pairs_per_image : int or None
        Pairs matched per image at most, the largest overlaps first; a spanning forest of the
        overlap graph is kept whatever the cap. None: every pair above ``min_overlap``.
    min_convergence_deg, max_convergence_deg : float, float or None
        Bounds of the angle between two images' lines of sight at their overlap's centre,
        degrees; the lower one for stereo only (tie points need none), None: no upper one.
    keep_candidates : bool
        Keep every candidate of every pair in the result (:attr:`TiePoints.pairs`, for
        ``diagnostics()``); False: the kept matches only, the others counted
        (:meth:`PairMatches.compact`), so that a large block's results stay small.
    """

    max_keypoints: int = 20000
    cell_px: int = 128
    contrast_threshold: float = 0.02
    search_px: float | None = None
    dem_sigma_m: float = 10.0
    ratio: float = 0.8
    bias_keypoints: int = 1000
    candidates: int = 64
    order: int = 1
    k: float = 3.0
    half_px: int = 7
    refine_search_px: int = 3
    min_score: float = 0.7
    sigma_px: float | None = None
    id_prefix: str = "tp"
    min_overlap: float = 0.1
    max_pairs_per_image: int | None = 10
    min_convergence_deg: float = 0.0
    max_convergence_deg: float | None = None
    keep_candidates: bool = True

    def __post_init__(self) -> None:
        def need(ok: bool, name: str, what: str) -> None:
            if not ok:
                raise MatchError(f"match option {name} must be {what}, got "
                                 f"{getattr(self, name)!r}")

        for name in ("max_keypoints", "cell_px", "bias_keypoints", "candidates"):
            need(_is_int(getattr(self, name)) and getattr(self, name) >= 1, name,
                 "an integer >= 1")
        need(_is_int(self.half_px) and self.half_px >= 2, "half_px", "an integer >= 2")
        need(_is_int(self.refine_search_px) and self.refine_search_px >= 1, "refine_search_px",
             "an integer >= 1")
        need(self.order in (0, 1, 2), "order", "0, 1 or 2")
        for name in ("contrast_threshold", "dem_sigma_m", "k"):
            need(_positive(getattr(self, name)), name, "a number > 0")
        need(self.search_px is None or _positive(self.search_px), "search_px",
             "a number > 0 (or None)")
        need(self.sigma_px is None or _positive(self.sigma_px), "sigma_px",
             "a number > 0 (or None)")
        need(_positive(self.ratio) and self.ratio <= 1, "ratio", "in (0, 1]")
        need(math.isfinite(self.min_score) and -1 <= self.min_score <= 1, "min_score",
             "in [-1, 1]")
        need(isinstance(self.min_overlap, int | float) and not isinstance(self.min_overlap, bool)
             and 0 <= self.min_overlap <= 1, "min_overlap", "in [0, 1]")
        need(self.max_pairs_per_image is None or (_is_int(self.max_pairs_per_image)
                                                  and self.max_pairs_per_image >= 1),
             "max_pairs_per_image", "an integer >= 1 (or None)")
        top = 180.0 if self.max_convergence_deg is None else self.max_convergence_deg
        need(isinstance(self.min_convergence_deg, int | float)
             and isinstance(top, int | float) and 0 <= self.min_convergence_deg <= top <= 180,
             "min_convergence_deg", "in [0, max_convergence_deg] (degrees, max <= 180)")
        need(isinstance(self.keep_candidates, bool), "keep_candidates", "True or False")
        need(isinstance(self.id_prefix, str) and "," not in self.id_prefix
             and self.id_prefix.strip() == self.id_prefix, "id_prefix",
             "a text without commas or surrounding spaces")

    def replace(self, **changes: Any) -> MatchOptions:
        """A copy with some options changed (checked)."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise MatchError(f"unknown match option(s) {unknown}; options: "
                             f"{', '.join(f.name for f in fields(self))}")
        return replace(self, **changes)


def _is_int(value: Any) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _positive(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) \
        and math.isfinite(value) and value > 0


@dataclass(frozen=True, eq=False)
class MatchImage:
    """An image to match: its pixels and the model that addresses them.

    Attributes
    ----------
    id : str
        The image's name in the ``image`` column of the measurements.
    image : ImageSource or ArrayImage
        The pixels (:func:`geoblock.io.open_image`); the first band is matched.
    model : SensorModel
        The model of the image's pixels (the given model, shifted when the image is a crop of
        its scene).
    offset : (float, float)
        Added to the image's pixels to give the pixels of the model as given (the crop's
        offset in the scene; ``(0, 0)`` otherwise).
    """

    id: str
    image: OpenedImage
    model: SensorModel
    offset: tuple[float, float] = (0.0, 0.0)

    @property
    def name(self) -> str:
        """The image's file (or name) for messages."""
        return str(getattr(self.image, "path", self.id))

    @classmethod
    def from_files(cls, image_id: str, image: Any, model: Any = None, *,
             crop_offset: tuple[float, float] | None = None, crop: bool = True,
             force: bool = False, names: Mapping[str, str] | None = None) -> MatchImage:
        """Open an image and its model and reconcile them.

        Parameters
        ----------
        image_id : str
        image : path or anything :func:`geoblock.io.open_image` accepts
        model : SensorModel, path or None
            The model, or its file (:func:`geoblock.open_model`); None: the model stored in
            the image file (e.g. its GeoTIFF RPC tags), as ``geoblock ortho`` finds it.
        crop_offset : (float, float), optional
            The scene pixel of the image's first pixel, when the image is a crop of the
            model's scene and does not say so itself (a pixel-unit geotransform).
        crop : bool
            False: take the image's pixels as the model's, whatever the shapes.
        force : bool
            True: use the model even when its image ids differ from the image's
            (:func:`geoblock.models.crop.model_for_image`).
        names : mapping, optional
            How refusals name the ways out (:func:`~geoblock.models.crop.model_for_image`).

        Raises
        ------
        ModelImageMismatchError
            The model carries image ids that differ from the image's (``force=False``).
        CropError
            The image does not fit the model (shapes differ with no crop offset, or the crop
            lies outside the scene); the message names the image.
        GeoblockError
            The image or the model cannot be read (names the file).
        """
        from geoblock.io.images import open_image
        from geoblock.io.models import open_model
        from geoblock.models.crop import CroppedModel, model_for_image

        source = open_image(image)
        given = open_model(source.path) if model is None else (
            open_model(model) if isinstance(model, str | os.PathLike) else model)
        fitted = model_for_image(given, source, crop_offset=crop_offset, crop=crop,
                                 names=names, force=force)
        offset = (0.0, 0.0)
        if fitted is not given and isinstance(fitted, CroppedModel):
            base = given.offset if isinstance(given, CroppedModel) else (0.0, 0.0)
            offset = (fitted.offset[0] - base[0], fitted.offset[1] - base[1])
        return cls(str(image_id), source, fitted, offset)


# ============================================================================== one pair
def _union(windows: Sequence[tuple[int, int, int, int]]) -> tuple[int, int, int, int]:
    return (min(w[0] for w in windows), max(w[1] for w in windows),
            min(w[2] for w in windows), max(w[3] for w in windows))


def _pad(window: tuple[int, int, int, int], pad: float, shape: tuple[int, int]
         ) -> tuple[int, int, int, int]:
    p = int(math.ceil(pad))
    return (max(0, window[0] - p), min(shape[0], window[1] + p),
            max(0, window[2] - p), min(shape[1], window[3] + p))


def _inside_window(kp: Keypoints, window: tuple[int, int, int, int]) -> np.ndarray:
    return ((kp.row >= window[0]) & (kp.row <= window[1] - 1)
            & (kp.col >= window[2]) & (kp.col <= window[3] - 1))


def _accuracy_m(model: SensorModel) -> float | None:
    """The location accuracy a model states (``location_accuracy_m``; a crop's scene's)."""
    inner = getattr(model, "model", model)
    for m in (model, inner):
        value = getattr(m, "location_accuracy_m", None)
        if isinstance(value, int | float) and math.isfinite(value) and value > 0:
            return float(value)
    return None


def _search_px(a: MatchImage, b: MatchImage, lap: Overlap, options: MatchOptions) -> float:
    """The first pass' window radius in B, pixels (:attr:`MatchOptions.search_px`)."""
    if options.search_px is not None:
        return float(options.search_px)
    acc = (_accuracy_m(a.model), _accuracy_m(b.model))
    gsd = ground_sample_distance(b.model, *lap.centre_b, lap.height_m)
    if acc[0] is None or acc[1] is None or not (math.isfinite(gsd) and gsd > 0):
        return DEFAULT_SEARCH_PX
    return max(3.0 * math.hypot(acc[0], acc[1]) / gsd, MIN_SEARCH_PX)


def _nearest_descriptors(desc_a: np.ndarray, desc_b: np.ndarray, cand: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row of ``cand`` (indices into B, -1 for none): the best candidate, the best and
    second-best descriptor distances (inf where missing)."""
    n, k = cand.shape
    best = np.full(n, -1, np.intp)
    d1 = np.full(n, np.inf)
    d2 = np.full(n, np.inf)
    if n == 0 or k == 0:
        return best, d1, d2
    step = max(1, (1 << 16) // k)
    for start in range(0, n, step):  # chunks of points, each vectorised (memory bound)
        sl = slice(start, min(start + step, n))
        c = cand[sl]
        diff = desc_b[np.maximum(c, 0)] - desc_a[sl, None, :]
        dist = np.sqrt(np.einsum("nkd,nkd->nk", diff, diff, dtype=np.float64))
        dist[c < 0] = np.inf
        order = np.argsort(dist, axis=1)[:, :2]
        rows = np.arange(c.shape[0])
        best[sl] = np.where(np.isfinite(dist[rows, order[:, 0]]), c[rows, order[:, 0]], -1)
        d1[sl] = dist[rows, order[:, 0]]
        d2[sl] = dist[rows, order[:, 1]] if k > 1 else np.inf
    return best, d1, d2


def _window_candidates(tree: Any, kp_b: Keypoints, pred_row: np.ndarray, pred_col: np.ndarray,
                       epi_row: np.ndarray, epi_col: np.ndarray, r_perp: np.ndarray,
                       r_par: np.ndarray, k: int) -> np.ndarray:
    """Indices of B's keypoints (up to ``k`` nearest, -1 for none) inside each window: at most
    ``r_perp`` across the epipolar direction and ``r_par`` along it from the prediction."""
    n = pred_row.size
    nb = len(kp_b)
    if n == 0 or nb == 0:
        return np.full((n, 0), -1, np.intp)
    k = min(k, nb)
    radius = float(np.max(np.hypot(r_perp, r_par)))
    _, idx = tree.query(np.column_stack([pred_row, pred_col]), k=k,
                        distance_upper_bound=radius)
    idx = np.asarray(idx).reshape(n, k)
    found = idx < nb
    safe = np.where(found, idx, 0)
    perp, par, _ = split_residuals(kp_b.row[safe] - pred_row[:, None],
                                   kp_b.col[safe] - pred_col[:, None],
                                   epi_row[:, None], epi_col[:, None])
    inside = found & (np.abs(perp) <= r_perp[:, None]) & (np.abs(par) <= r_par[:, None])
    return np.where(inside, idx, -1)


def _first_of_groups(key: np.ndarray, score: np.ndarray) -> np.ndarray:
    """Mask of the entry with the smallest ``score`` per value of ``key``."""
    if not key.size:
        return np.zeros(0, bool)
    order = np.lexsort((score, key))
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    keep = np.zeros(key.size, bool)
    keep[order[first]] = True
    return keep


def _match_pair(a: MatchImage, keypoints_a: Keypoints, b: MatchImage, kp_b: Keypoints,
                dem: DemSource, lap: Overlap, search: float, options: MatchOptions,
                progress: Progress) -> PairMatches:
    """Match one pair of images (steps 2-6 of the module docstring) given their keypoints,
    with the first pass' window radius ``search`` (pixels of B); the result's arrays are in
    each image's own pixels, its indices into ``keypoints_a`` and ``kp_b``. The pixels are
    read a tile at a time (:func:`geoblock.match.tasks.refine_in_tiles`).

    Raises
    ------
    MatchError
        No keypoint of A is predicted inside B, or no consistent bias can be found (names
        both files and what to try).
    """
    from scipy.spatial import cKDTree

    say = progress
    start_time = time.perf_counter()
    names = f"{a.name} and {b.name}"
    if lap.window_a is None:
        raise MatchError(f"{names}: the images do not overlap on the DEM")
    in_a = np.flatnonzero(_inside_window(keypoints_a, lap.window_a))
    kp_a = keypoints_a.subset(in_a)
    if not len(kp_a) or not len(kp_b):
        empty = a.name if not len(kp_a) else b.name
        raise MatchError(f"{empty}: no SIFT keypoint where {names} overlap (a flat, "
                         "saturated or nodata area?); try a lower contrast threshold")
    pred = predict(a.model, b.model, dem, kp_a.row, kp_a.col)
    ok = np.flatnonzero(pred.ok)
    if not ok.size:
        raise MatchError(f"{names}: no keypoint of the first is predicted inside the second "
                         "(through the models and the DEM): do they overlap?")
    kp_a = kp_a.subset(ok)
    in_a = in_a[ok]
    pred = Prediction(pred.row[ok], pred.col[ok], pred.h[ok], pred.epi_row[ok],
                      pred.epi_col[ok], pred.ok[ok])
    centre, scale = scale_of(a.model.shape)
    norm = pred.epipolar_norm
    tree = cKDTree(np.column_stack([kp_b.row, kp_b.col]))

    # --- first pass: the bias, from the strongest keypoints of every cell, wide windows
    order = np.argsort(kp_a.rank, kind="stable")[:options.bias_keypoints]
    h_tol = 3.0 * options.dem_sigma_m
    r_perp = np.full(order.size, search)
    r_par = search + h_tol * norm[order]
    cand = _window_candidates(tree, kp_b, pred.row[order], pred.col[order],
                              pred.epi_row[order], pred.epi_col[order], r_perp, r_par,
                              max(options.candidates, 256))
    best, d1, d2 = _nearest_descriptors(kp_a.descriptors[order], kp_b.descriptors, cand)
    passed = (best >= 0) & (d1 < options.ratio * d2)
    sel = order[passed]
    bb = best[passed]
    d_row = kp_b.row[bb] - pred.row[sel]
    d_col = kp_b.col[bb] - pred.col[sel]
    agree = consensus(d_row, d_col, pred.epi_row[sel], pred.epi_col[sel], tolerance_px=3.0,
                      height_tolerance_m=h_tol)
    if agree.sum() < MIN_BIAS_MATCHES:
        raise MatchError(
            f"{names}: no consistent offset between the images within {search:.0f} px of the "
            f"models' prediction ({int(agree.sum())} matches agree, {MIN_BIAS_MATCHES} "
            "needed): the models may disagree by more (give a larger search radius), the "
            "images may not overlap, or their content may differ (clouds, seasons)")
    # SIFT's positions agree within a pixel or so, the DEM within a few times its accuracy
    first = consistent(kp_a.row[sel], kp_a.col[sel], d_row, d_col, pred.epi_row[sel],
                       pred.epi_col[sel], agree, order=options.order, k=options.k,
                       min_sigma_px=0.3, max_sigma_px=1.0, sigma_px=1.0,
                       sigma_h_m=options.dem_sigma_m, max_sigma_h_m=2 * options.dem_sigma_m,
                       centre=centre, scale=scale)
    off = first.bias.mean(kp_a.row[sel][first.inlier], kp_a.col[sel][first.inlier])
    say(f"  {a.id} & {b.id}: models' offset {off[0]:+.1f}, "
        f"{off[1]:+.1f} px from {int(first.inlier.sum())} of "
        f"{sel.size} first-pass matches (window {search:.0f} px)")

    # --- second pass: every keypoint, narrow windows around the corrected prediction
    br, bc = first.bias(kp_a.row, kp_a.col)
    row_p = pred.row + br
    col_p = pred.col + bc
    tol_perp = max(options.k * first.sigma_px, 1.5)
    r_perp = np.full(len(kp_a), tol_perp)
    r_par = options.k * np.sqrt(first.sigma_px**2 + (first.sigma_h_m * norm) ** 2)
    r_par = np.maximum(r_par, tol_perp)
    cand = _window_candidates(tree, kp_b, row_p, col_p, pred.epi_row, pred.epi_col, r_perp,
                              r_par, options.candidates)
    has = (cand >= 0).any(axis=1)
    idx = np.flatnonzero(has)
    best, d1, d2 = _nearest_descriptors(kp_a.descriptors[idx], kp_b.descriptors, cand[idx])
    n = idx.size
    status = np.full(n, "kept", dtype="<U11")
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(d2), d1 / d2, 0.0)
    status[~(ratio < options.ratio)] = "ratio"
    # one match per keypoint of B, and per position of A (SIFT gives a keypoint one entry per
    # dominant orientation): the closest descriptor wins
    live = status == "kept"
    pos_a = np.round(kp_a.row[idx] * 100) * 1e7 + np.round(kp_a.col[idx] * 100)
    for key in (best, pos_a):
        won = np.zeros(n, bool)
        won[live] = _first_of_groups(key[live], d1[live])
        status[live & ~won] = "unique"
        live = status == "kept"

    # --- sub-pixel refinement
    ra, ca = kp_a.row[idx], kp_a.col[idx]
    rb, cb = kp_b.row[np.maximum(best, 0)], kp_b.col[np.maximum(best, 0)]
    row_b, col_b = rb.copy(), cb.copy()
    score = np.full(n, np.nan)
    live_i = np.flatnonzero(live)
    if live_i.size:
        from geoblock.match.tasks import refine_in_tiles

        jac = local_affine(a.model, b.model, dem, ra[live_i], ca[live_i])
        row_b[live_i], col_b[live_i], score[live_i], refined = refine_in_tiles(
            a, b, ra[live_i], ca[live_i], rb[live_i], cb[live_i], jac, options)
        status[live_i[refined != RefineStatus.CONVERGED]] = "correlation"

    # --- outlier test on the refined matches
    live = status == "kept"
    d_row = row_b - pred.row[idx]
    d_col = col_b - pred.col[idx]
    perp = np.full(n, np.nan)
    height = np.full(n, np.nan)
    bias, s_p, s_h = first.bias, first.sigma_px, first.sigma_h_m
    # start from the matches the first pass' bias and scales accept; the refined positions
    # can only be closer than SIFT's: the first pass' scales are the ceilings
    br, bc = first.bias(ra, ca)
    perp0, par0, norm0 = split_residuals(d_row - br, d_col - bc, pred.epi_row[idx],
                                         pred.epi_col[idx])
    start = live & (np.abs(perp0) <= options.k * first.sigma_px) & (
        np.abs(par0) <= options.k * np.hypot(first.sigma_px, first.sigma_h_m * norm0))
    if start.sum() >= MIN_BIAS_MATCHES:
        final = consistent(ra, ca, d_row, d_col, pred.epi_row[idx], pred.epi_col[idx], start,
                           order=options.order, k=options.k, sigma_px=first.sigma_px,
                           sigma_h_m=first.sigma_h_m, max_sigma_px=min(first.sigma_px, 0.5),
                           max_sigma_h_m=first.sigma_h_m, centre=centre, scale=scale,
                           eligible=live)
        status[live & final.epipolar] = "epipolar"
        status[live & final.height] = "height"
        perp, height = final.perp, final.height_m
        bias, s_p, s_h = final.bias, final.sigma_px, final.sigma_h_m
    else:
        status[live] = "epipolar"  # too few to test: none is trusted
    return PairMatches(
        a.id, b.id, len(kp_a), len(kp_b), int(pred.ok.sum()), in_a[idx],
        np.where(best >= 0, best, -1), ra, ca, row_b, col_b, pred.row[idx], pred.col[idx],
        ratio, score, perp, height, status, bias, s_p, s_h, search,
        time.perf_counter() - start_time)


# ============================================================================== N images
def _pairs(images: Sequence[MatchImage], dem: DemSource, options: MatchOptions,
           progress: Progress, graph: PairGraph | None = None, scheduler: Any = "threads"
           ) -> list[tuple[int, int, Overlap]]:
    """The selected pairs (:func:`~geoblock.match.pairs.select_pairs` with the options'
    thresholds, reported before any matching) with their overlaps in pixels (footprints and
    overlaps computed as tasks on ``scheduler``)."""
    import uuid

    import dask

    from geoblock.match.tasks import run_tasks

    if graph is None:
        graph = select_pairs(images, dem, min_overlap=options.min_overlap,
                             max_pairs_per_image=options.max_pairs_per_image,
                             min_convergence_deg=options.min_convergence_deg,
                             max_convergence_deg=options.max_convergence_deg,
                             scheduler=scheduler)
    elif graph.image_ids != tuple(im.id for im in images):
        raise MatchError(f"the pair graph's images {list(graph.image_ids)[:5]} are not the "
                         f"images matched {[im.id for im in images][:5]}")
    progress(graph.report())
    selected = graph.selected.tolist()
    run = uuid.uuid4().hex[:12]  # keys unique to this run (a cluster may run others)
    laps = run_tasks({f"overlap-{p}": dask.delayed(overlap, pure=False)(
        images[i].model, images[j].model, dem, dask_key_name=f"overlap-{run}-{p}")
        for p, (i, j) in enumerate(selected)}, scheduler)
    pairs = []
    for (i, j), lap in zip(selected, laps.values(), strict=True):
        if lap.fraction > 0:
            progress(f"  {images[i].id} & {images[j].id}: {100 * lap.fraction:.0f} % of "
                     f"{images[i].id} overlaps {images[j].id}")
            pairs.append((i, j, lap))
    return pairs


def match_images(images: Sequence[MatchImage], dem: DemSource, *,
                 options: MatchOptions | None = None,
                 progress: Progress | None = None,
                 pairs: PairGraph | None = None, scheduler: Any = "threads") -> TiePoints:
    """Tie points between images, guided by their sensor models and a DEM.

    Parameters
    ----------
    images : sequence of MatchImage
        Two or more images with their models (:meth:`MatchImage.from_files`); the first of a
        track's images is its reference.
    dem : DemSource
        Heights above the ellipsoid (:func:`geoblock.open_dem`).
    options : MatchOptions, optional
    progress : callable, optional
        Called with messages (the pair graph, overlaps, keypoints, each pair's outcome).
    pairs : PairGraph, optional
        The pairs to match (:func:`geoblock.match.select_pairs` of these images); default
        selected with the options' thresholds.
    scheduler : {"threads", "processes", "synchronous"} or distributed.Client
        Where the tasks run (:mod:`geoblock.match.tasks`: one per image's keypoints, one per
        pair): the result is the same, byte for byte, on every one.

    Returns
    -------
    TiePoints
        Measurements sorted by id then image (in the order given).

    Raises
    ------
    MatchError
        Fewer than two images, duplicate ids, no pair overlaps, or no pair could be matched
        (an image without keypoints where it overlaps another, a pair without a consistent
        bias: the message names the files). A pair that fails while others succeed is
        reported (``progress``, :attr:`TiePoints.failed`) and left out.

    Examples
    --------
    >>> import geoblock
    >>> from geoblock.match import MatchImage, match_images
    >>> images = [MatchImage.from_files("left", "left.tif", "left.geom"),
    ...           MatchImage.from_files("right", "right.tif", "right.geom")]  # doctest: +SKIP
    >>> tps = match_images(images, geoblock.open_dem("N44E005.hgt"))  # doctest: +SKIP
    >>> geoblock.io.write_points("tp.csv", tps.to_columns())  # doctest: +SKIP
    """
    start = time.perf_counter()
    options = options or MatchOptions()
    say = progress or (lambda message: None)
    images = list(images)
    if len(images) < 2:
        raise MatchError(f"matching needs at least two images, got {len(images)}")
    ids = [im.id for im in images]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise MatchError(f"duplicate image id(s) {dup}: each image needs its own id")
    say(f"overlaps of {len(images)} images on the DEM")
    pairs_ = _pairs(images, dem, options, say, pairs, scheduler)
    if not pairs_:
        from geoblock.dem import coverage_gap

        gaps = [f"{im.name}: {gap}" for im in images
                if (gap := coverage_gap(dem, im.model)) is not None]
        if gaps:
            raise MatchError("the DEM cannot place the images' rays: " + "; ".join(gaps))
        names = ", ".join(im.name for im in images)
        raise MatchError(f"no two of the images overlap on the DEM ({names}): check the "
                         "models, the DEM and that the images show the same area")
    from geoblock.match.tasks import match_pairs, refine_links
    from geoblock.match.tracks import join_tracks

    searches = [_search_px(images[i], images[j], lap, options) for i, j, lap in pairs_]
    windows: list[tuple[int, int, int, int] | None] = []
    pad = 2 * (options.half_px + options.refine_search_px + 4)  # the correlation's patches
    for k, im in enumerate(images):
        shape = (int(im.image.shape[0]), int(im.image.shape[1]))
        boxes = [_pad(lap.window_a, pad, shape) for i, _, lap in pairs_
                 if i == k and lap.window_a is not None]
        # B's side: where the models put it, give or take the first pass' window
        boxes += [_pad(lap.window_b, pad + r, shape) for (_, j, lap), r in zip(pairs_, searches,
                                                                            strict=True)
                  if j == k and lap.window_b is not None]
        windows.append(_union(boxes) if boxes else None)
    say(f"matching {len(pairs_)} pairs of {sum(w is not None for w in windows)} images "
        f"({scheduler if isinstance(scheduler, str) else 'distributed'} scheduler)")
    counts, outcome, failures, positions_b = match_pairs(
        images, dem, pairs_, searches, windows, options, scheduler, say)
    done = [p for p, res in enumerate(outcome) if res is not None]
    failed = tuple((images[i].id, images[j].id, str(failures[p]))
                   for p, (i, j, _) in enumerate(pairs_) if outcome[p] is None)
    if not done:  # nothing to join: the first failure says why
        more = f" (and {len(failed) - 1} more pair(s) failed)" if len(failed) > 1 else ""
        raise MatchError(f"{failed[0][2]}{more}")
    if failed:
        say(f"{len(failed)} of {len(pairs_)} pairs failed (their images are tied by the other "
            "pairs only): " + "; ".join(f"{a} & {b}" for a, b, _ in failed[:10])
            + (", ..." if len(failed) > 10 else ""))
    results = [r for r in outcome if r is not None]
    sigmas = [options.sigma_px if options.sigma_px is not None
              else max(res.sigma_px / math.sqrt(2.0), 0.05) for res in results]
    columns, dropped = join_tracks(
        images, counts, results, [pairs_[p][:2] for p in done], options, sigmas,
        lambda jobs: refine_links(images, dem, jobs, options, scheduler),
        [positions_b[p] for p in done])
    order = columns.pop("_order")
    columns = {k: v[order] for k, v in columns.items()}
    return TiePoints(columns["id"], columns["image"], columns["row"], columns["col"],
                     columns["sigma"], tuple(results), tuple(ids),
                     {im.id: n for im, n in zip(images, counts, strict=True)},
                     dropped,
                     time.perf_counter() - start,
                     {im.id: im.offset for im in images}, failed)


def match_block(block: Any, *, dem: DemSource | None = None,
                options: MatchOptions | None = None,
                progress: Progress | None = None, scheduler: Any = "threads") -> TiePoints:
    """Tie points between all overlapping images of a block file.

    Parameters
    ----------
    block : path or geoblock.io.blocks.Block
        The block file ``geoblock adjust`` reads: each image's ``model`` and ``raster``
        (required here), and the ``[dem]``.
    dem : DemSource, optional
        Overrides the block's DEM.
    options : MatchOptions, optional
        Its ``dem_sigma_m`` is the block's ``dem.sigma``, and the pair-selection options
        (``min_overlap``, ``max_pairs_per_image``, ``min_convergence_deg``,
        ``max_convergence_deg``) the block's ``[match]`` table's, where left at their defaults.
    progress : callable, optional
    scheduler : {"threads", "processes", "synchronous"} or distributed.Client
        Where the tasks run (:func:`match_images`).

    Returns
    -------
    TiePoints
        In the pixels of the models the block names, ids as the block's images.

    Raises
    ------
    BlockFileError
        An image has no ``raster``, or the block has no DEM and none is given.
    GeoblockError
        What opening an image, a model or the DEM raises (names the file).
    """
    from geoblock.errors import BlockFileError
    from geoblock.io.blocks import Block, read_block

    spec = block if isinstance(block, Block) else read_block(block)
    name = "<block>" if isinstance(block, Block) else str(block)
    missing = [f"images[{k}] ({im.id})" for k, im in enumerate(spec.images)
               if im.raster is None]
    if missing:
        raise BlockFileError(f"{name}: {', '.join(missing)} name(s) no 'raster': geoblock "
                             "match needs each image's pixels (raster = \"image.tif\")")
    options = options or MatchOptions()
    if spec.dem is not None and spec.dem.sigma is not None \
            and options.dem_sigma_m == MatchOptions.dem_sigma_m:
        options = options.replace(dem_sigma_m=float(spec.dem.sigma))
    from_block = {k: v for k, v in spec.match.items()
                  if getattr(options, k) == getattr(MatchOptions, k)}
    if from_block:
        try:
            options = options.replace(**from_block)
        except MatchError as exc:
            raise BlockFileError(f"{name}: [match]: {exc}") from None
    if dem is None:
        if spec.dem is None:
            raise BlockFileError(f"{name}: no [dem] table, and no DEM given: matching "
                                 "needs the terrain to predict where the images meet")
        dem = spec.dem.to_source(name)
    images = [MatchImage.from_files(im.id, im.raster, im.model) for im in spec.images]
    return match_images(images, dem, options=options, progress=progress, scheduler=scheduler)


def write_tie_points(path: str | os.PathLike[str], tie_points: TiePoints,
                     ictp_share: float = 0.0) -> None:
    """Write the measurements as the image-measurement CSV ``geoblock adjust`` reads
    (``id, image, row, col, sigma, kind``; ``"-"``: standard output).

    Raises
    ------
    GeoblockIOError
        The file cannot be written (names it).
    """
    from geoblock.io.points import write_points

    write_points(path, tie_points.to_columns(ictp_share))
