"""Ground control from a reference orthoimage: :func:`match_reference` (``geoblock match
--reference``).

Each image is matched against the reference **at the reference's resolution**:

1. **Overlap.** The image's outline (a lattice of its pixels on the DEM through its model) in
   the reference's CRS, intersected with the reference: a window of the reference's grid. An
   image whose footprint misses the reference is named in the statistics (``no overlap``),
   not an error for the others.
2. **Warp.** The image is orthorectified onto that window of the reference's own grid (its
   CRS, pixel size and pixel phase) through its model and the DEM
   (:func:`geoblock.ortho.source_coordinates`, the orthorectifier's lattice). When the image
   is finer than the reference it is first area-averaged by the integer factor
   ``f = round(gsd_reference / gsd_image)`` (``f x f`` blocks of pixels: 0.5 m imagery
   against a 10 m reference is averaged 20 x 20) so that the warp does not alias; the
   averaged image is then resampled bicubically.
3. **Shift.** The warped image and the reference are phase-correlated on tiles of the window
   (:data:`TILE_PX`); the shift most tiles agree on within :data:`CONSENSUS_PX`
   (:func:`geoblock.match.consistency.consensus`) starts the matching.
4. **Patches.** Nodes of the reference's grid, spread evenly over the overlap (at most
   ``max_points``), are matched by :func:`geoblock.match.refine.refine_matches`: the
   reference's ``(2 half_px + 1)^2`` patch around the node is the template (never moved), the
   warped image is searched around the node plus the shift by normalised cross-correlation,
   then least-squares matching gives the sub-pixel position. Area matching on a grid rather
   than SIFT: two orthos on one grid differ by a shift and radiometry only, which is what
   correlation measures best (a tenth of a pixel), and it needs no keypoint at the coarse
   reference's scale. A DEM error moves the warped image along the image's **parallax
   direction** (the ground its line of sight meets, per metre of height, in reference pixels):
   each patch is started at points ``2 refine_search_px`` apart along it, out to three times
   the DEM's accuracy, and the best correlation wins (at a 10 m reference one start; at a
   0.5 m reference over SRTM several).
5. **Outliers.** The offsets (warped minus reference, reference pixels) are tested as tie
   points are (:func:`geoblock.match.consistency.consistent`, the parallax direction as the
   epipolar one): a low-order polynomial of the reference pixel (the image model's
   misregistration, order ``order``) fitted robustly, matches beyond ``k`` robust standard
   deviations across the parallax direction, or beyond the DEM's height scatter along it,
   rejected (``offset``), to a fixed point.
6. **Control points.** A kept match is a ground control point: its **ground** is where the
   reference shows the feature, the node's centre (the reference's geotransform, to WGS84),
   at the DEM's height there (metres above the ellipsoid, the geoid applied as the DEM
   source does); its **image position** is where the raw image shows the same feature: the
   matched position ``q = node + offset`` of the warped image taken back through the warp's
   own mapping, the image model's projection of the ground at ``q`` (``q``'s map position at
   the DEM's height there), in the raw image's pixels.

Sigmas
------
Horizontal, per axis::

    sigma_e = sigma_n = sqrt((CE90_ref / 2.1460)^2 + (sigma_match_px * gsd_ref)^2)

``2.1460`` is the circular-normal CE90 factor (NSSDA: ``CE90 = 2.1460 sigma`` for equal
axes); ``sigma_match_px`` the matching precision in reference pixels, by default the robust
scale of the kept offsets' residuals about the fitted polynomial across the parallax direction
(what the matches disagree by, as the tie-point sigma is measured), at least
:data:`MIN_SIGMA_MATCH_PX`; ``gsd_ref`` the reference's
pixel size in metres. Vertical::

    sigma_h = sqrt(sigma_DEM^2 + (|grad h| * sigma_e)^2)

the DEM's accuracy plus the height change under a horizontally uncertain position, ``|grad
h|`` from central differences of the DEM over ``+- max(sigma_e, half a DEM post, 1 m)``. The
image rows carry :data:`IMAGE_SIGMA_PX` pixels: the matching error is in the ground sigmas
already (counting it in both would weigh each point twice as loosely).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.io.images import OpenedImage
    from geoblock.match.pipeline import MatchImage
    from geoblock.ortho.grid import OutputGrid

__all__ = ["CE90_FACTOR", "ReferenceControl", "ReferenceMatches", "ReferenceOptions",
           "ReferenceOrtho", "match_reference", "reference_sigmas"]

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
                     gsd_reference_m: float, dem_sigma_m: float, slope: Any
                     ) -> tuple[float, np.ndarray]:
    """The sigmas of control points from a reference orthoimage (module docstring).

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

    Returns
    -------
    sigma_horizontal : float
        ``sigma_e = sigma_n``, metres.
    sigma_h : ndarray, (N,)
        Metres.

    Examples
    --------
    >>> s, h = reference_sigmas(10.0, 0.2, 10.0, 5.0, [0.0, 0.5])
    >>> round(s, 3), [round(v, 3) for v in h]
    (4.99, [5.0, 5.585])
    """
    s = math.hypot(reference_accuracy_ce90_m / CE90_FACTOR, sigma_match_px * gsd_reference_m)
    g = np.abs(np.asarray(slope, float))
    return s, np.sqrt(dem_sigma_m**2 + (g * s) ** 2)


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
    def open(cls, source: Any, band: int = 1) -> ReferenceOrtho:
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


@dataclass(frozen=True, eq=False)
class ReferenceControl:
    """Ground control points from a reference orthoimage: the ground rows, the image rows and
    what became of every candidate.

    Attributes
    ----------
    ground : dict of str to ndarray
        ``id, kind, source, lon, lat, h, sigma_e, sigma_n, sigma_h`` (kind ``gcp``, source
        ``reference:<file name>``; degrees, metres above the WGS84 ellipsoid, metres), (P,).
    measurements : dict of str to ndarray
        ``id, image, row, col, sigma, kind``: the raw image's pixels (the model's as given,
        the scene's for a crop), sigma in pixels, kind ``gcp``, (P,).
    images : tuple of ReferenceMatches
        Per image, in the order given.
    reference : str
        The reference's path.
    gsd_reference_m : float
    accuracy_ce90_m : float
    dem_sigma_m : float
    seconds : float
    """

    ground: Mapping[str, np.ndarray]
    measurements: Mapping[str, np.ndarray]
    images: tuple[ReferenceMatches, ...]
    reference: str
    gsd_reference_m: float
    accuracy_ce90_m: float
    dem_sigma_m: float
    seconds: float

    def __len__(self) -> int:
        return int(np.asarray(self.ground["id"]).size)

    @property
    def source(self) -> str:
        """``reference:<file name>``, the ``source`` column of the ground rows."""
        return f"reference:{Path(self.reference).name}"

    def image(self, image_id: str) -> ReferenceMatches:
        """The statistics of one image (``KeyError`` naming the ids otherwise)."""
        for m in self.images:
            if m.image == image_id:
                return m
        raise KeyError(f"no image {image_id!r}; images: {[m.image for m in self.images]}")

    def write(self, ground: str | os.PathLike[str], image: str | os.PathLike[str] | None, *,
              overwrite: bool = False) -> None:
        """Write the ground rows and the image rows (:func:`geoblock.io.write_points`,
        atomically).

        Parameters
        ----------
        ground : path or ``"-"``
        image : path, ``"-"`` or None
            None: the image rows are written elsewhere (e.g. with the tie points).
        overwrite : bool
            Replace files that exist; without it an existing file is refused before anything
            is written.

        Raises
        ------
        OutputExistsError, OutputIsInputError, OutputPathError
            As :func:`geoblock.io.outputs.check_outputs`.
        GeoblockIOError
            A file cannot be written.
        """
        from geoblock.io.outputs import check_outputs
        from geoblock.io.points import write_points

        check_outputs({"ground": ground, "image": image}, {"reference": self.reference},
                      overwrite=overwrite, overwrite_hint="pass overwrite=True to replace it")
        write_points(ground, dict(self.ground))
        if image is not None:
            write_points(image, dict(self.measurements))

    def diagnostics(self) -> dict[str, np.ndarray]:
        """Every candidate of every image: ``image, ref_row, ref_col`` (the node, reference
        pixels), ``offset_row, offset_col`` (warped image minus reference, reference pixels;
        NaN where not matched), ``score`` (the correlation) and ``status`` (``kept`` or the
        test that rejected it)."""
        parts = [m for m in self.images if m.status_of.size]
        if not parts:
            return {k: np.zeros(0) for k in ("image", "ref_row", "ref_col", "offset_row",
                                              "offset_col", "score", "status")}
        return {"image": np.concatenate([np.full(m.status_of.size, m.image) for m in parts]),
                "ref_row": np.concatenate([m.ref_row for m in parts]),
                "ref_col": np.concatenate([m.ref_col for m in parts]),
                "offset_row": np.concatenate([m.d_row for m in parts]),
                "offset_col": np.concatenate([m.d_col for m in parts]),
                "score": np.concatenate([m.score for m in parts]),
                "status": np.concatenate([m.status_of for m in parts])}

    def counts(self) -> dict[str, int]:
        """Candidates, kept and rejected per test, summed over the images."""
        total: dict[str, int] = {}
        for m in self.images:
            for key, value in m.counts().items():
                total[key] = total.get(key, 0) + value
        return total

    def summary(self) -> str:
        """One line: points, images, rejections, sigmas, points per second."""
        c = self.counts()
        rejected = ", ".join(f"{n} {c.get(n, 0)}" for n in REFERENCE_REJECTIONS if c.get(n, 0))
        matched = sum(m.status == "matched" for m in self.images)
        s = np.asarray(self.ground["sigma_e"])
        sig = f"; sigma_e {float(np.median(s)):.2f} m" if s.size else ""
        rate = len(self) / self.seconds if self.seconds > 0 else math.inf
        return (f"{len(self)} reference control points in {matched} of {len(self.images)} "
                f"image(s) from {Path(self.reference).name} ({self.gsd_reference_m:g} m, CE90 "
                f"{self.accuracy_ce90_m:g} m): {c.get('candidates', 0)} candidates (rejected: "
                f"{rejected or 'none'}){sig}; {rate:.0f} points/s ({self.seconds:.1f} s)")


# ============================================================================== matching
def _as_images(images: Any) -> list[MatchImage]:
    from geoblock.match.pipeline import MatchImage

    if isinstance(images, Mapping):
        out = []
        for image_id, value in images.items():
            if isinstance(value, MatchImage):
                out.append(value)
                continue
            try:
                model, raster = value
            except (TypeError, ValueError):
                raise MatchError(f"images[{image_id!r}] must be a (model, raster) pair or a "
                                 f"MatchImage, got {type(value).__name__}") from None
            out.append(MatchImage.from_files(str(image_id), raster, model))
        return out
    out = list(images)
    for k, im in enumerate(out):
        if not isinstance(im, MatchImage):
            raise MatchError(f"images[{k}] must be a MatchImage (or give a mapping of id to "
                             f"(model, raster)), got {type(im).__name__}")
    return out


def match_reference(images: Mapping[str, Any] | Sequence[MatchImage], reference: Any,
                    dem: DemSource, *, reference_accuracy_ce90_m: float, dem_sigma_m: float,
                    options: ReferenceOptions | None = None,
                    progress: Progress | None = None) -> ReferenceControl:
    """Ground control points from a reference orthoimage and a DEM (module docstring).

    Parameters
    ----------
    images : mapping of str to (model, raster), or sequence of MatchImage
        The images: id to ``(model, raster)`` (a :class:`~geoblock.models.SensorModel` or its
        file, and a raster path or :class:`~geoblock.io.images.ImageSource`), or
        :class:`~geoblock.match.MatchImage` (:meth:`~geoblock.match.MatchImage.from_files`).
    reference : path, ImageSource or ReferenceOrtho
        The reference orthoimage: a georeferenced raster in any CRS (projected or
        geographic), any dtype, its nodata honoured; north-up.
    dem : DemSource
        Heights above the ellipsoid (:func:`geoblock.open_dem`): the warp's terrain and the
        control points' heights.
    reference_accuracy_ce90_m : float
        The reference's absolute accuracy, CE90, metres (the adjustment weighs each point by
        it; module docstring).
    dem_sigma_m : float
        The DEM's accuracy (1 sigma), metres.
    options : ReferenceOptions, optional
    progress : callable, optional
        Called with one-line messages.

    Returns
    -------
    ReferenceControl
        Points numbered image by image; an image without overlap has no points and the
        status ``no overlap``.

    Raises
    ------
    MatchError
        An accuracy that is not a positive number, no image overlaps the reference (names the
        reference and the images), or no point survives the tests.
    GeoblockError
        What opening an image, a model or the reference raises (names the file).

    Examples
    --------
    >>> import geoblock
    >>> from geoblock.match import match_reference
    >>> control = match_reference({"right": ("right.geom", "right.tif")}, "left_ortho.tif",
    ...                           geoblock.open_dem("N44E005.hgt"),
    ...                           reference_accuracy_ce90_m=8.5, dem_sigma_m=10.0)  # doctest: +SKIP
    >>> control.write("ground.csv", "image.csv")  # doctest: +SKIP
    """
    from geoblock.match._reference_warp import match_one

    start = time.perf_counter()
    options = options or ReferenceOptions()
    say = progress or (lambda message: None)
    for name, value in (("reference_accuracy_ce90_m", reference_accuracy_ce90_m),
                        ("dem_sigma_m", dem_sigma_m)):
        if not (isinstance(value, int | float) and not isinstance(value, bool)
                and math.isfinite(value) and value > 0):
            raise MatchError(f"{name} must be a number > 0 (metres), got {value!r}")
    ref = reference if isinstance(reference, ReferenceOrtho) else \
        ReferenceOrtho.open(reference, options.band)
    ims = _as_images(images)
    if not ims:
        raise MatchError("match_reference: no image given")
    ids = [im.id for im in ims]
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise MatchError(f"duplicate image id(s) {dup}: each image needs its own id")
    say(f"reference {ref.name}: {ref.shape[0]} x {ref.shape[1]} px of {ref.gsd_m:.3g} m, "
        f"CE90 {reference_accuracy_ce90_m:g} m")
    results = []
    parts: list[dict[str, np.ndarray]] = []
    for im in ims:
        res, rows = match_one(im, ref, dem, float(reference_accuracy_ce90_m), options, say,
                              float(dem_sigma_m))
        say("  " + res.summary())
        results.append(res)
        parts.append(rows)
    if all(r.status == "no overlap" for r in results):
        names = ", ".join(im.name for im in ims)
        raise MatchError(f"no image overlaps the reference {ref.path} (its data, on the DEM): "
                         f"{names}; check the reference's area and CRS")
    total = sum(p["row"].size for p in parts)
    if total == 0:
        lines = "; ".join(r.summary() for r in results)
        raise MatchError(f"no control point from the reference {ref.path}: {lines}")
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    width = max(5, len(str(total)))
    ids_out = np.char.add(options.id_prefix, np.char.zfill(np.arange(total).astype(str), width))
    sigma_h = np.empty(total)
    sigma_e = np.empty(total)
    for_image = np.concatenate([np.full(p["row"].size, k) for k, p in enumerate(parts)])
    for k, res in enumerate(results):
        sel = for_image == k
        if not sel.any():
            continue
        s, h = reference_sigmas(reference_accuracy_ce90_m, res.sigma_match_px, ref.gsd_m,
                                dem_sigma_m, cat["slope"][sel])
        sigma_e[sel] = s
        sigma_h[sel] = h
    source = f"reference:{ref.name}"
    ground = {"id": ids_out, "kind": np.full(total, "gcp"), "source": np.full(total, source),
              "lon": cat["lon"], "lat": cat["lat"], "h": cat["h"], "sigma_e": sigma_e,
              "sigma_n": sigma_e.copy(), "sigma_h": sigma_h}
    image_ids = np.array(ids, dtype=str)[for_image]
    measurements = {"id": ids_out, "image": image_ids, "row": cat["row"], "col": cat["col"],
                    "sigma": np.full(total, IMAGE_SIGMA_PX), "kind": np.full(total, "gcp")}
    return ReferenceControl(ground, measurements, tuple(results), ref.path, ref.gsd_m,
                            float(reference_accuracy_ce90_m), float(dem_sigma_m),
                            time.perf_counter() - start)
