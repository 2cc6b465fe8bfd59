"""What matching found: :class:`PairMatches` (every candidate of a pair and its fate) and
:class:`TiePoints` (the kept matches of a block, as tracks, and what ``geoblock match``
writes).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from geoblock.errors import MatchError
from geoblock.match.consistency import Bias

if TYPE_CHECKING:
    from geoblock.adjust.observations import ImagePoints

__all__ = ["REJECTIONS", "PairMatches", "TiePoints"]

#: Why a candidate match was rejected, in the order the tests apply.
REJECTIONS = ("ratio", "unique", "correlation", "epipolar", "height", "track")


@dataclass(frozen=True, eq=False)
class PairMatches:
    """The matching of one pair of images (A, B): every candidate and its fate.

    The arrays have one entry per candidate: a keypoint of A with at least one keypoint of B
    inside its window. Pixels are each image's own (the rasters'); :class:`TiePoints` has the
    models' pixels.

    Attributes
    ----------
    image_a, image_b : str
        Image ids.
    keypoints_a, keypoints_b : int
        Keypoints of A in the overlap with B, and of B in its part of it.
    predicted : int
        Keypoints of A whose prediction falls inside B.
    index_a, index_b : ndarray of int, (N,)
        The keypoints (of each image's :class:`~geoblock.match.features.Keypoints`).
    row_a, col_a : ndarray, (N,)
        A's keypoint, pixels.
    row_b, col_b : ndarray, (N,)
        The match in B after refinement (B's keypoint where the refinement failed), pixels.
    pred_row, pred_col : ndarray, (N,)
        The models' prediction in B, pixels.
    ratio : ndarray, (N,)
        Best over second-best descriptor distance in the window (0 with one candidate).
    score : ndarray, (N,)
        Normalised cross-correlation of the refinement (NaN when not refined).
    perp : ndarray, (N,)
        Residual across the epipolar direction after the bias, pixels.
    height_m : ndarray, (N,)
        Residual along it as a height, metres.
    status : ndarray of str, (N,)
        ``kept`` or the test that rejected the candidate (:data:`REJECTIONS`).
    bias : Bias
        The models' disagreement fitted to the kept matches (B minus prediction, pixels of B
        as a polynomial of A's pixels).
    sigma_px : float
        Robust scale of the kept matches' ``perp``, pixels.
    sigma_h_m : float
        Robust scale of their height parallax, metres.
    search_px : float
        The first pass' window radius used, pixels.
    seconds : float
    not_held : mapping of str to int
        Candidates not held in the arrays, per status (:meth:`compact`: the rejected ones
        of a pair matched without keeping its candidates); :meth:`counts` includes them.
    """

    image_a: str
    image_b: str
    keypoints_a: int
    keypoints_b: int
    predicted: int
    index_a: np.ndarray
    index_b: np.ndarray
    row_a: np.ndarray
    col_a: np.ndarray
    row_b: np.ndarray
    col_b: np.ndarray
    pred_row: np.ndarray
    pred_col: np.ndarray
    ratio: np.ndarray
    score: np.ndarray
    perp: np.ndarray
    height_m: np.ndarray
    status: np.ndarray
    bias: Bias
    sigma_px: float
    sigma_h_m: float
    search_px: float
    seconds: float
    not_held: Mapping[str, int] = field(default_factory=dict)

    @property
    def kept(self) -> np.ndarray:
        """Mask of the kept matches, (N,)."""
        return self.status == "kept"

    def counts(self) -> dict[str, int]:
        """Candidates, kept, and rejected per test (those not held included)."""
        out = {"candidates": int(self.status.size) + sum(self.not_held.values()),
               "kept": int(self.kept.sum()) + int(self.not_held.get("kept", 0))}
        out.update({name: int((self.status == name).sum()) + int(self.not_held.get(name, 0))
                    for name in REJECTIONS})
        return out

    def compact(self) -> PairMatches:
        """The kept matches only, the others counted in :attr:`not_held` (what the tracks
        need, without the rejected candidates' arrays: a large block's pairs' results in a
        fraction of the memory); itself when nothing was kept."""
        keep = self.kept
        if not keep.any() or keep.all():
            return self
        names, counts = np.unique(self.status[~keep], return_counts=True)
        not_held = dict(self.not_held)
        for name, count in zip(names.tolist(), counts.tolist(), strict=True):
            not_held[name] = not_held.get(name, 0) + int(count)
        arrays = {f: getattr(self, f)[keep] for f in (
            "index_a", "index_b", "row_a", "col_a", "row_b", "col_b", "pred_row", "pred_col",
            "ratio", "score", "perp", "height_m", "status")}
        return replace(self, **arrays, not_held=not_held)

    def offset_px(self) -> tuple[float, float]:
        """The models' disagreement where the matches are: the bias's mean over the kept
        matches (over every candidate when none is kept), ``(d_row, d_col)`` in B, pixels.

        Not the bias's constant term: that is its value at A's (scene) centre, an
        extrapolation for a pair that overlaps at A's edge or for a crop of a large scene.
        """
        at = self.kept if self.kept.any() else np.ones(self.status.size, bool)
        return self.bias.mean(self.row_a[at], self.col_a[at])

    def summary(self) -> str:
        """One line: keypoints, candidates, kept, rejections, the bias and the scales."""
        c = self.counts()
        rejected = ", ".join(f"{name} {c[name]}" for name in REJECTIONS if c[name])
        shift = self.offset_px()
        return (f"{self.image_a} & {self.image_b}: {self.keypoints_a} + {self.keypoints_b} "
                f"keypoints, {c['candidates']} candidates, {c['kept']} kept"
                f" (rejected: {rejected or 'none'}); models' offset {shift[0]:+.2f}, "
                f"{shift[1]:+.2f} px (row, col), scatter {self.sigma_px:.2f} px across the "
                f"epipolar direction, {self.sigma_h_m:.1f} m in height; {self.seconds:.1f} s")


@dataclass(frozen=True, eq=False)
class TiePoints:
    """Tie points measured in images: one row per measurement.

    Attributes
    ----------
    id : ndarray of str, (M,)
        Tie-point id; a point measured in more than two images has one id.
    image : ndarray of str, (M,)
        Image id.
    row, col : ndarray, (M,)
        Pixels of the image's model as given (the scene's for a crop).
    sigma : ndarray, (M,)
        Measurement standard deviation, pixels.
    pairs : tuple of PairMatches
    images : tuple of str
        The image ids, in the order given.
    keypoints : mapping of str to int
        Keypoints detected per image.
    dropped_tracks : int
        Tracks dropped: they joined two keypoints of one image.
    seconds : float
        Wall-clock time of the whole matching.
    offsets : mapping of str to (float, float)
        Per image, what was added to the raster's pixels to give the model's
        (:attr:`MatchImage.offset`).
    failed : tuple of (str, str, str)
        The selected pairs that could not be matched: ``(image_a, image_b, why)``; their
        images are tied by the other pairs only.
    """

    id: np.ndarray
    image: np.ndarray
    row: np.ndarray
    col: np.ndarray
    sigma: np.ndarray
    pairs: tuple[PairMatches, ...]
    images: tuple[str, ...]
    keypoints: Mapping[str, int]
    dropped_tracks: int
    seconds: float
    offsets: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    failed: tuple[tuple[str, str, str], ...] = ()

    def __len__(self) -> int:
        return int(self.id.size)

    @property
    def n_points(self) -> int:
        """Number of tie points (distinct ids)."""
        return int(np.unique(self.id).size)

    def kinds(self, ictp_share: float = 0.0) -> np.ndarray:
        """``"tp"`` per measurement, or ``"ictp"`` for the points kept as independent check
        tie points (Teo et al.: measured, not adjusted, ray-traced onto the DEM from each
        image afterwards to measure the images' relative accuracy).

        Parameters
        ----------
        ictp_share : float
            Share of the points, in [0, 0.5]: every ``round(1 / ictp_share)``-th point in id
            order (so spread over the images like the points themselves, and the same for
            the same inputs). 0: none.

        Raises
        ------
        MatchError
            ``ictp_share`` outside [0, 0.5].
        """
        share = float(ictp_share)
        if not 0.0 <= share <= 0.5:
            raise MatchError(f"ictp_share must be in [0, 0.5], got {ictp_share!r}")
        kind = np.full(self.id.size, "tp", dtype="<U4")
        if share > 0.0 and self.id.size:
            ids, index = np.unique(self.id, return_inverse=True)
            every = max(2, round(1.0 / share))
            kind[(index % every) == every - 1] = "ictp"
        return kind

    def to_columns(self, ictp_share: float = 0.0) -> dict[str, np.ndarray]:
        """The image-measurement columns ``id, image, row, col, sigma, kind`` (``tp``, or
        ``ictp`` for a share of the points: :meth:`kinds`) that :func:`geoblock.io.write_points`
        writes and ``geoblock adjust`` reads."""
        return {"id": self.id, "image": self.image, "row": self.row, "col": self.col,
                "sigma": self.sigma, "kind": self.kinds(ictp_share)}

    def image_points(self, ictp_share: float = 0.0) -> ImagePoints:
        """The measurements as :class:`geoblock.adjust.ImagePoints` (kinds as
        :meth:`to_columns`)."""
        from geoblock.adjust.observations import ImagePoints

        return ImagePoints.from_columns(self.to_columns(ictp_share), source="geoblock match")

    def diagnostics(self) -> dict[str, np.ndarray]:
        """Every candidate held of every pair (the kept ones only where the matching did not
        keep the candidates: ``MatchOptions.keep_candidates``): ``pair, image_a, image_b,
        row_a, col_a, row_b, col_b`` (the models' pixels), ``pred_row, pred_col`` (the
        models' prediction in B, before the bias), ``offset_row, offset_col`` (match minus
        prediction), ``ratio, score, perp_px, height_m, status``."""
        parts: dict[str, list[np.ndarray]] = {}
        for p in self.pairs:
            oa = self.offsets.get(p.image_a, (0.0, 0.0))
            ob = self.offsets.get(p.image_b, (0.0, 0.0))
            n = p.status.size
            cols = {
                "pair": np.full(n, f"{p.image_a}&{p.image_b}"),
                "image_a": np.full(n, p.image_a), "image_b": np.full(n, p.image_b),
                "row_a": p.row_a + oa[0], "col_a": p.col_a + oa[1],
                "row_b": p.row_b + ob[0], "col_b": p.col_b + ob[1],
                "pred_row": p.pred_row + ob[0], "pred_col": p.pred_col + ob[1],
                "offset_row": p.row_b - p.pred_row, "offset_col": p.col_b - p.pred_col,
                "ratio": p.ratio, "score": p.score, "perp_px": p.perp,
                "height_m": p.height_m, "status": p.status,
            }
            for key, value in cols.items():
                parts.setdefault(key, []).append(np.asarray(value))
        return {k: np.concatenate(v) for k, v in parts.items()} if parts else {}

    def counts(self) -> dict[str, int]:
        """Candidates, kept and rejected per test, summed over the pairs."""
        total: dict[str, int] = {}
        for p in self.pairs:
            for key, value in p.counts().items():
                total[key] = total.get(key, 0) + value
        return total

    def summary(self) -> str:
        """One line: points, measurements, keypoints, candidates, kept, rejections,
        matches per second."""
        c = self.counts()
        rejected = ", ".join(f"{name} {c.get(name, 0)}" for name in REJECTIONS
                             if c.get(name, 0))
        kp = sum(self.keypoints.values())
        rate = c.get("kept", 0) / self.seconds if self.seconds > 0 else math.inf
        failed = f" ({len(self.failed)} failed)" if self.failed else ""
        return (f"{self.n_points} tie points, {len(self)} measurements in {len(self.images)} "
                f"images from {len(self.pairs)} pair(s){failed}: {kp} keypoints, "
                f"{c.get('candidates', 0)} candidates, {c.get('kept', 0)} matches kept "
                f"(rejected: {rejected or 'none'}); {rate:.0f} matches/s "
                f"({self.seconds:.1f} s)")
