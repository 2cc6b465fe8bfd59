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
A reference's stated accuracy (``CE90_ref``) is above all a **misregistration common to all
its points**: many points do not average it out, and weighing them as independent would let
the adjustment claim an absolute accuracy far better than the reference's. So the ground
rows carry it as the sigma of a common shift, per axis::

    sigma_shift_e = sigma_shift_n = CE90_ref / 2.1460          (sigma_shift_h = 0)

which the adjustment estimates as one translation per reference (the ``source``), with that
prior; ``2.1460`` is the circular-normal CE90 factor (NSSDA: ``CE90 = 2.1460 sigma`` for
equal axes). Each point's own horizontal error is the matching's, and the reference's local
(point-to-point) error when it is stated (``local_CE90``,
:attr:`ReferenceOptions.local_accuracy_ce90_m`, default 0)::

    sigma_e = sigma_n = sqrt((local_CE90 / 2.1460)^2 + (sigma_match_px * gsd_ref)^2)

``sigma_match_px`` the matching precision in reference pixels, by default the robust scale of
the kept offsets' residuals about the fitted polynomial across the parallax direction (what
the matches disagree by, as the tie-point sigma is measured), at least
:data:`MIN_SIGMA_MATCH_PX`; ``gsd_ref`` the reference's pixel size in metres. Vertical::

    sigma_h = sqrt(sigma_DEM^2 + (|grad h| * sqrt(sigma_e^2 + sigma_shift_e^2))^2)

the DEM's accuracy plus the height change under a horizontally uncertain position (point by
point: the slope differs), ``|grad h|`` from central differences of the DEM over
``+- max(sigma, half a DEM post, 1 m)``. The image rows carry :data:`IMAGE_SIGMA_PX` pixels:
the matching error is in the ground sigmas already (counting it in both would weigh each
point twice as loosely).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.match.pipeline import MatchImage

from geoblock.match._reference_types import (
    CE90_FACTOR,
    IMAGE_SIGMA_PX,
    REFERENCE_REJECTIONS,
    Progress,
    ReferenceMatches,
    ReferenceOptions,
    ReferenceOrtho,
    reference_sigmas,
)

__all__ = ["CE90_FACTOR", "ReferenceControl", "ReferenceMatches", "ReferenceOptions",
           "ReferenceOrtho", "match_reference", "reference_sigmas"]


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
        OutputExistsError
            A file exists and ``overwrite`` is false (named).
        OutputIsInputError
            A file is the reference orthoimage.
        GeoblockIOError
            A file cannot be written.
        """
        from geoblock.errors import OutputExistsError, OutputIsInputError
        from geoblock.io.points import write_points

        for name, path in (("ground", ground), ("image", image)):
            if path is None or str(path) == "-":
                continue
            if Path(path).resolve() == Path(self.reference).resolve():
                raise OutputIsInputError(f"the {name} point file {str(path)!r} is the reference "
                                         "orthoimage; choose another path")
            if Path(path).exists() and not overwrite:
                raise OutputExistsError(f"the {name} point file {str(path)!r} exists; pass "
                                        "overwrite=True to replace it")
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
        sig = (f"; sigma_e {float(np.median(s)):.2f} m each and "
               f"{self.accuracy_ce90_m / CE90_FACTOR:.2f} m common (the reference's CE90 / "
               f"{CE90_FACTOR})" if s.size else "")
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
        ReferenceOrtho.read(reference, options.band)
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
        s, h, _ = reference_sigmas(reference_accuracy_ce90_m, res.sigma_match_px,
                                   ref.gsd_m, dem_sigma_m, cat["slope"][sel],
                                   options.local_accuracy_ce90_m)
        sigma_e[sel] = s
        sigma_h[sel] = h
    source = f"reference:{ref.name}"
    shift = float(reference_accuracy_ce90_m) / CE90_FACTOR  # one common error per reference
    ground = {"id": ids_out, "kind": np.full(total, "gcp"), "source": np.full(total, source),
              "lon": cat["lon"], "lat": cat["lat"], "h": cat["h"], "sigma_e": sigma_e,
              "sigma_n": sigma_e.copy(), "sigma_h": sigma_h,
              "sigma_shift_e": np.full(total, shift), "sigma_shift_n": np.full(total, shift),
              "sigma_shift_h": np.zeros(total)}
    image_ids = np.array(ids, dtype=str)[for_image]
    measurements = {"id": ids_out, "image": image_ids, "row": cat["row"], "col": cat["col"],
                    "sigma": np.full(total, IMAGE_SIGMA_PX), "kind": np.full(total, "gcp")}
    return ReferenceControl(ground, measurements, tuple(results), ref.path, ref.gsd_m,
                            float(reference_accuracy_ce90_m), float(dem_sigma_m),
                            time.perf_counter() - start)
