"""The values of reference-orthoimage control (:mod:`geoblock.match.reference`): options,
the reference raster, per-image outcomes, the sigma formula and the tuning constants.

Apart from :mod:`geoblock.match.reference` so that the warp and match of one image
(:mod:`geoblock.match._reference_warp`) and the driver both import them without a cycle.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError

if TYPE_CHECKING:
    from geoblock.io.images import OpenedImage
    from geoblock.ortho.grid import OutputGrid

Progress = Callable[[str], None]

#: CE90 over the per-axis standard deviation of a circular normal error (NSSDA, FGDC-STD-
#: 007.3-1998: ``CE90 = 2.1460 sigma``, sqrt(-2 ln 0.1)).
CE90_FACTOR = 2.1460
#: Floor of the matching precision estimated from the offsets' scatter, reference pixels.
MIN_SIGMA_MATCH_PX = 0.1
#: The ``sigma`` of the image rows, raw pixels (the matching error is in the ground sigmas).
IMAGE_SIGMA_PX = 0.05
#: Side of the phase-correlation tiles of step 3, reference pixels (smaller windows: the
#: window itself).
TILE_PX = 128
#: Tiles at most phase-correlated per image.
MAX_TILES = 64
#: Tiles' shifts within this many reference pixels of each other agree (step 3).
CONSENSUS_PX = 1.5
#: Rejections of a candidate, in the order the tests apply.
REFERENCE_REJECTIONS = ("nodata", "correlation", "offset")


@dataclass(frozen=True)
class ReferenceOptions:
    """Options of :func:`match_reference`.

    Attributes
    ----------
    half_px : int
        Patch half-size, reference pixels: ``(2 half_px + 1)^2`` patches.
    max_points : int
        Candidate nodes per image at most, spread evenly over its overlap with the reference.
    search_px : float or None
        How far the image's model may place it off the reference, reference pixels: the
        phase correlation's tiles are at least four times this. None: three times the
        model's stated location accuracy plus the reference's (1 sigma), at least 8.
    refine_search_px : int
        Largest correction of a node's start (its tiles' shift) by the correlation, pixels.
    min_score : float
        Smallest normalised cross-correlation kept.
    order : {0, 1, 2}
        Order of the offsets' polynomial in the outlier test (lowered with few matches).
    k : float
        Rejection threshold, robust standard deviations.
    sigma_match_px : float or None
        The matching precision in the sigma formula, reference pixels; None: estimated per
        image (module docstring).
    local_accuracy_ce90_m : float
        The reference's local (relative, point-to-point) accuracy, CE90 metres: errors that
        differ from one point to the next (an ortho's relief displacement where its own DEM
        was wrong, its seamlines), added to each point's own sigma. 0 (the default): the
        points' own error is the matching's alone, and the adjustment's sigma0 says how much
        they scatter beyond it.
    band : int
        Band of the reference matched (1-based).
    image_band : int
        Band of the images matched (1-based).
    id_prefix : str
        Point ids are ``<id_prefix><number>``, numbered image by image in the order given.
    """

    half_px: int = 10
    max_points: int = 1000
    search_px: float | None = None
    refine_search_px: int = 3
    min_score: float = 0.6
    order: int = 1
    k: float = 3.0
    sigma_match_px: float | None = None
    local_accuracy_ce90_m: float = 0.0
    band: int = 1
    image_band: int = 1
    id_prefix: str = "ref"

    def __post_init__(self) -> None:
        def need(ok: bool, name: str, what: str) -> None:
            if not ok:
                raise MatchError(f"reference option {name} must be {what}, got "
                                 f"{getattr(self, name)!r}")

        def is_int(v: Any) -> bool:
            return isinstance(v, int | np.integer) and not isinstance(v, bool)

        def positive(v: Any) -> bool:
            return isinstance(v, int | float) and not isinstance(v, bool) \
                and math.isfinite(v) and v > 0

        need(is_int(self.half_px) and self.half_px >= 2, "half_px", "an integer >= 2")
        for name in ("max_points", "refine_search_px", "band", "image_band"):
            need(is_int(getattr(self, name)) and getattr(self, name) >= 1, name,
                 "an integer >= 1")
        need(self.order in (0, 1, 2), "order", "0, 1 or 2")
        need(positive(self.k), "k", "a number > 0")
        need(self.search_px is None or positive(self.search_px), "search_px",
             "a number > 0 (or None)")
        need(self.sigma_match_px is None or positive(self.sigma_match_px), "sigma_match_px",
             "a number > 0 (or None)")
        need(isinstance(self.local_accuracy_ce90_m, int | float)
             and not isinstance(self.local_accuracy_ce90_m, bool)
             and math.isfinite(self.local_accuracy_ce90_m) and self.local_accuracy_ce90_m >= 0,
             "local_accuracy_ce90_m", "a number >= 0 (metres)")
        need(isinstance(self.min_score, int | float) and -1 <= self.min_score <= 1,
             "min_score", "in [-1, 1]")
        need(isinstance(self.id_prefix, str) and bool(self.id_prefix)
             and "," not in self.id_prefix and self.id_prefix.strip() == self.id_prefix,
             "id_prefix", "a non-empty text without commas or surrounding spaces")

    def replace(self, **changes: Any) -> ReferenceOptions:
        """A copy with some options changed (checked)."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise MatchError(f"unknown reference option(s) {unknown}; options: "
                             f"{', '.join(f.name for f in fields(self))}")
        return replace(self, **changes)


def reference_sigmas(reference_accuracy_ce90_m: float, sigma_match_px: float,
                     gsd_reference_m: float, dem_sigma_m: float, slope: Any,
                     local_accuracy_ce90_m: float = 0.0) -> tuple[float, np.ndarray, float]:
    """The sigmas of control points from a reference orthoimage (module docstring).

    The reference's stated accuracy is a misregistration common to all its points (it does
    not average out over many of them): it is the sigma of a **common shift**
    (``sigma_shift_e/n`` of the ground CSV, one translation per reference estimated by the
    adjustment); each point's own horizontal error is the matching's and the reference's local
    error.

    Parameters
    ----------
    reference_accuracy_ce90_m : float
        The reference's circular error at 90 %, metres.
    sigma_match_px : float
        Matching precision, reference pixels.
    gsd_reference_m : float
        The reference's pixel size, metres.
    dem_sigma_m : float
        The DEM's accuracy (1 sigma), metres.
    slope : array_like, (N,)
        ``|grad h|`` of the DEM at the points (metres per metre).
    local_accuracy_ce90_m : float
        The reference's local accuracy (CE90, metres; 0: none stated).

    Returns
    -------
    sigma_horizontal : float
        ``sigma_e = sigma_n``: each point's own error, ``sqrt((local_CE90 / 2.1460)**2 +
        (sigma_match_px * gsd_reference_m)**2)``, metres.
    sigma_h : ndarray, (N,)
        ``sqrt(sigma_DEM**2 + (|grad h| * sigma_total)**2)``, metres, with ``sigma_total``
        the point's whole horizontal sigma (own and common: the height the DEM gives under a
        shifted position differs by the slope times the shift, point by point).
    sigma_shift : float
        ``sigma_shift_e = sigma_shift_n = CE90 / 2.1460``, metres: the common error.

    Examples
    --------
    >>> s, h, c = reference_sigmas(10.0, 0.2, 10.0, 5.0, [0.0, 0.5])
    >>> round(s, 3), [round(v, 3) for v in h], round(c, 3)
    (2.0, [5.0, 5.585], 4.66)
    """
    own = math.hypot(float(local_accuracy_ce90_m) / CE90_FACTOR,
                     float(sigma_match_px) * float(gsd_reference_m))
    common = float(reference_accuracy_ce90_m) / CE90_FACTOR
    g = np.abs(np.asarray(slope, float))
    return own, np.sqrt(dem_sigma_m**2 + (g * math.hypot(own, common)) ** 2), common


# ============================================================================== the reference
@dataclass(frozen=True, eq=False)
class ReferenceOrtho:
    """A reference orthoimage opened for matching.

    Attributes
    ----------
    path : str
    image : ImageSource or ArrayImage
    crs : pyproj.CRS
    transform : affine.Affine
        North-up (GDAL's corner-based geotransform).
    band : int
        1-based band matched.
    gsd_m : float
        Pixel size in metres (the geometric mean of both axes; for a geographic CRS at the
        reference's centre).
    """

    path: str
    image: OpenedImage
    crs: Any
    transform: Any
    band: int
    gsd_m: float

    @property
    def name(self) -> str:
        """The file name (what the ``source`` column says: ``reference:<name>``)."""
        return Path(self.path).name

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.image.shape[0]), int(self.image.shape[1]))

    def grid(self, window: tuple[int, int, int, int] | None = None) -> OutputGrid:
        """The reference's grid, or a ``(r0, r1, c0, c1)`` window of it."""
        from affine import Affine

        from geoblock.ortho.grid import OutputGrid

        r0, r1, c0, c1 = window if window is not None else (0, self.shape[0], 0, self.shape[1])
        t = self.transform
        origin = Affine(t.a, 0.0, t.c + c0 * t.a, 0.0, t.e, t.f + r0 * t.e)
        return OutputGrid(self.crs, origin, (r1 - r0, c1 - c0))

    @classmethod
    def read(cls, source: Any, band: int = 1) -> ReferenceOrtho:
        """Open a georeferenced raster (any CRS pyproj knows, projected or geographic; any
        dtype; its nodata honoured).

        Raises
        ------
        MatchError
            No CRS, a geotransform that is not north-up, or no such band (names the file).
        GeoblockIOError
            The file cannot be read.
        """
        import pyproj

        from geoblock.io.images import open_image

        image = open_image(source)
        path = str(getattr(image, "path", source))
        if image.crs is None or image.transform is None:
            raise MatchError(f"reference {path}: no CRS or geotransform; a reference "
                             "orthoimage must be georeferenced (a GeoTIFF with its CRS)")
        t = image.transform
        if t.b != 0 or t.d != 0 or not t.a > 0 or not t.e < 0:
            raise MatchError(f"reference {path}: its geotransform is not north-up ({tuple(t)[:6]}"
                             "); warp it north-up first (gdalwarp without -t_srs keeps its "
                             "CRS)")
        if not 1 <= band <= image.bands:
            raise MatchError(f"reference {path}: no band {band} (it has {image.bands})")
        crs = pyproj.CRS.from_user_input(image.crs.to_wkt() if hasattr(image.crs, "to_wkt")
                                         else image.crs)
        gsd = _pixel_size_m(crs, t, image.shape)
        return cls(path, image, crs, t, band, gsd)


def _pixel_size_m(crs: Any, t: Any, shape: tuple[int, int]) -> float:
    """Geometric mean of the pixel's sides, metres."""
    if crs.is_geographic:
        from geoblock import coords

        x, y = t.c + t.a * shape[1] / 2.0, t.f + t.e * shape[0] / 2.0
        lon, lat = coords.transformer(crs, "EPSG:4326").transform(x, y)
        m = math.radians(1.0) * 6378137.0
        return math.sqrt(abs(t.a) * m * math.cos(math.radians(float(lat))) * abs(t.e) * m)
    unit = crs.axis_info[0].unit_conversion_factor if crs.axis_info else 1.0
    return math.sqrt(abs(t.a) * abs(t.e)) * float(unit or 1.0)


# ============================================================================== results
@dataclass(frozen=True, eq=False)
class ReferenceMatches:
    """The matching of one image against the reference: every candidate and its fate.

    Attributes
    ----------
    image : str
        Image id.
    status : str
        ``matched``, ``no overlap`` (its footprint misses the reference or its data) or
        ``no shift`` (no consistent shift between the warped image and the reference).
    window : (int, int, int, int) or None
        ``(r0, r1, c0, c1)`` of the reference matched.
    reduction : int
        The image's area-averaging factor before the warp.
    gsd_image_m : float
        The image's ground sample distance at its centre, metres.
    ref_row, ref_col : ndarray, (N,)
        The candidates' nodes, reference pixels (of the whole reference).
    d_row, d_col : ndarray, (N,)
        Offsets, warped image minus reference, reference pixels (NaN where not matched).
    score : ndarray, (N,)
        Normalised cross-correlation (NaN where not matched).
    status_of : ndarray of str, (N,)
        ``kept`` or the test that rejected the candidate (:data:`REFERENCE_REJECTIONS`).
    shift_px : (float, float)
        The image's misregistration against the reference, ``(d_row, d_col)`` in reference
        pixels: the fitted polynomial's mean over the kept matches (the tiles' shift when
        none is kept; NaN without overlap).
    sigma_match_px : float
        The matching precision used in the sigmas, reference pixels.
    seconds : float
    """

    image: str
    status: str
    window: tuple[int, int, int, int] | None = None
    reduction: int = 1
    gsd_image_m: float = math.nan
    ref_row: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ref_col: np.ndarray = field(default_factory=lambda: np.zeros(0))
    d_row: np.ndarray = field(default_factory=lambda: np.zeros(0))
    d_col: np.ndarray = field(default_factory=lambda: np.zeros(0))
    score: np.ndarray = field(default_factory=lambda: np.zeros(0))
    status_of: np.ndarray = field(default_factory=lambda: np.zeros(0, "<U11"))
    shift_px: tuple[float, float] = (math.nan, math.nan)
    sigma_match_px: float = math.nan
    seconds: float = 0.0

    @property
    def kept(self) -> np.ndarray:
        """Mask of the kept candidates, (N,)."""
        return self.status_of == "kept"

    def counts(self) -> dict[str, int]:
        """Candidates, kept, and rejected per test."""
        out = {"candidates": int(self.status_of.size), "kept": int(self.kept.sum())}
        out.update({n: int((self.status_of == n).sum()) for n in REFERENCE_REJECTIONS})
        return out

    def summary(self) -> str:
        """One line."""
        if self.status != "matched":
            return f"{self.image}: {self.status}"
        c = self.counts()
        rejected = ", ".join(f"{n} {c[n]}" for n in REFERENCE_REJECTIONS if c[n])
        return (f"{self.image}: {c['candidates']} candidates, {c['kept']} kept (rejected: "
                f"{rejected or 'none'}); shift {self.shift_px[0]:+.2f}, {self.shift_px[1]:+.2f}"
                f" reference px (row, col), matching sigma {self.sigma_match_px:.2f} px; "
                f"image averaged {self.reduction}x{self.reduction}; {self.seconds:.1f} s")
