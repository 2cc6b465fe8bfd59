"""Tie points from images, guided by the sensor models: ``geoblock match``.

* :func:`select_pairs` - which pairs to match, from the images' footprints on the DEM
  (:class:`PairGraph`: candidates, overlaps, convergence angles, components;
  :mod:`geoblock.match.pairs`);
* :func:`match_images` - tie points between two or more images (:class:`MatchImage`: pixels
  and model) over a DEM; :func:`match_block` - between the images of a block file;
* :class:`TiePoints` - the measurements (``id, image, row, col, sigma``, kind ``tp``) with
  every pair's candidates and why they were rejected (:class:`PairMatches`);
* the steps: :func:`~geoblock.match.features.detect_keypoints` (SIFT, spread),
  :func:`~geoblock.match.geometry.predict` (the models' prediction through the DEM and the
  epipolar direction), :func:`~geoblock.match.consistency.consistent` (the outlier test: a
  low-order image-space bias plus the height parallax along the epipolar direction),
  :func:`~geoblock.match.refine.refine_matches` (sub-pixel normalised cross-correlation, then
  least-squares matching, in the models' local geometry);
* :func:`least_squares_match` - least-squares matching (Gruen 1985: shift, radiometric gain
  and offset, by Gauss-Newton, with a per-patch :class:`LsmStatus`), the one solver of the
  refinement and of the seam measurement;
* :func:`match_reference` - ground control points from a reference orthoimage and a DEM
  (:class:`ReferenceControl`: ground rows of kind ``gcp`` with ``source = reference:<file>``
  and their image rows; :mod:`geoblock.match.reference`);
* :func:`seam_shift` - the misregistration of two neighbouring orthos measured on their pixels
  in their overlap (:class:`SeamShift`, :mod:`geoblock.match.seams`; ``geoblock demo``'s
  seams).

OpenCV (``cv2``) and scipy are imported when first used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from geoblock._lazy import lazy_names

if TYPE_CHECKING:
    from geoblock.match.consistency import Bias, Consistency, consensus, consistent, fit_bias
    from geoblock.match.features import Keypoints, detect_keypoints
    from geoblock.match.geometry import Overlap, Prediction, local_affine, overlap, predict
    from geoblock.match.lsm import LsmSolution, LsmStatus, least_squares_match
    from geoblock.match.pairs import Footprint, PairGraph, footprint, select_pairs
    from geoblock.match.pipeline import (
        DEFAULT_SEARCH_PX,
        REJECTIONS,
        MatchImage,
        MatchOptions,
        PairMatches,
        TiePoints,
        match_block,
        match_images,
        write_tie_points,
    )
    from geoblock.match.reference import (
        ReferenceControl,
        ReferenceMatches,
        ReferenceOptions,
        ReferenceOrtho,
        match_reference,
        reference_sigmas,
    )
    from geoblock.match.refine import Refined, RefineStatus, refine_matches
    from geoblock.match.seams import SeamShift, seam_shift

_LAZY = {
    "Bias": "geoblock.match.consistency",
    "Consistency": "geoblock.match.consistency",
    "consensus": "geoblock.match.consistency",
    "consistent": "geoblock.match.consistency",
    "fit_bias": "geoblock.match.consistency",
    "Keypoints": "geoblock.match.features",
    "detect_keypoints": "geoblock.match.features",
    "Overlap": "geoblock.match.geometry",
    "Prediction": "geoblock.match.geometry",
    "local_affine": "geoblock.match.geometry",
    "overlap": "geoblock.match.geometry",
    "predict": "geoblock.match.geometry",
    "LsmSolution": "geoblock.match.lsm",
    "LsmStatus": "geoblock.match.lsm",
    "least_squares_match": "geoblock.match.lsm",
    "Footprint": "geoblock.match.pairs",
    "PairGraph": "geoblock.match.pairs",
    "footprint": "geoblock.match.pairs",
    "select_pairs": "geoblock.match.pairs",
    "DEFAULT_SEARCH_PX": "geoblock.match.pipeline",
    "REJECTIONS": "geoblock.match.pipeline",
    "MatchImage": "geoblock.match.pipeline",
    "MatchOptions": "geoblock.match.pipeline",
    "PairMatches": "geoblock.match.pipeline",
    "TiePoints": "geoblock.match.pipeline",
    "match_block": "geoblock.match.pipeline",
    "match_images": "geoblock.match.pipeline",
    "write_tie_points": "geoblock.match.pipeline",
    "ReferenceControl": "geoblock.match.reference",
    "ReferenceMatches": "geoblock.match.reference",
    "ReferenceOptions": "geoblock.match.reference",
    "ReferenceOrtho": "geoblock.match.reference",
    "match_reference": "geoblock.match.reference",
    "reference_sigmas": "geoblock.match.reference",
    "Refined": "geoblock.match.refine",
    "RefineStatus": "geoblock.match.refine",
    "refine_matches": "geoblock.match.refine",
    "SeamShift": "geoblock.match.seams",
    "seam_shift": "geoblock.match.seams",
}

__getattr__, __dir__ = lazy_names(__name__, _LAZY)

__all__ = [
    "Bias",
    "Consistency",
    "DEFAULT_SEARCH_PX",
    "Footprint",
    "Keypoints",
    "LsmSolution",
    "LsmStatus",
    "MatchImage",
    "MatchOptions",
    "Overlap",
    "PairGraph",
    "PairMatches",
    "Prediction",
    "REJECTIONS",
    "RefineStatus",
    "ReferenceControl",
    "ReferenceMatches",
    "ReferenceOptions",
    "ReferenceOrtho",
    "Refined",
    "SeamShift",
    "TiePoints",
    "consensus",
    "consistent",
    "detect_keypoints",
    "fit_bias",
    "footprint",
    "least_squares_match",
    "local_affine",
    "match_block",
    "match_images",
    "match_reference",
    "overlap",
    "predict",
    "reference_sigmas",
    "refine_matches",
    "seam_shift",
    "select_pairs",
    "write_tie_points",
]
