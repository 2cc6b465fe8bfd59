"""SIFT keypoints spread over an image window: :func:`detect_keypoints`.

OpenCV's SIFT (``cv2.SIFT_create``, Lowe 2004) finds blob-like features at several scales and
describes each by a 128-value histogram of gradient orientations, invariant to rotation, scale
and (after normalisation) to contrast. geoblock runs it:

* on 8-bit pixels: each chunk is stretched linearly between the 0.5th and 99.5th percentiles
  of its valid pixels (SIFT's contrast threshold is relative to a 0-255 range; 11- or 12-bit
  satellite pixels in ``uint16`` use a few hundred of their 65536 values);
* chunk by chunk (``chunk_px`` square, with a ``CHUNK_MARGIN_PX`` border read around it and
  only the keypoints of the chunk's core kept), so that memory stays bounded whatever the
  window's size;
* away from nodata: the pixels equal to the image's nodata value (and the
  ``NODATA_MARGIN_PX`` around them) are masked out, so that no descriptor straddles the edge
  of the data;
* spread out: the window is cut into cells of ``cell_px``; each cell keeps at most its share
  of ``max_keypoints`` (the strongest by SIFT's response), so that textured areas do not take
  every keypoint.

Coordinates are the image's pixels (pixel centres at integer row/col, as in
:mod:`geoblock.pixels`; OpenCV's ``KeyPoint.pt`` is ``(x, y) = (col, row)`` with the same
convention).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError

if TYPE_CHECKING:
    from geoblock.io.images import OpenedImage

__all__ = ["CHUNK_MARGIN_PX", "NODATA_MARGIN_PX", "Keypoints", "detect_keypoints", "to_uint8"]

#: Pixels read around each detection chunk (SIFT's support at the scales that matter).
CHUNK_MARGIN_PX = 48
#: Pixels masked around nodata pixels (no descriptor reaching into them).
NODATA_MARGIN_PX = 8
#: Percentiles of the valid pixels stretched to 0 and 255.
STRETCH_PERCENTILES = (0.5, 99.5)


@dataclass(frozen=True, eq=False)
class Keypoints:
    """SIFT keypoints of one image.

    Attributes
    ----------
    row, col : ndarray, (N,)
        Position, pixels of the image (pixel centres at integers), float64.
    response : ndarray, (N,)
        SIFT's detector response (contrast of the extremum): larger is stronger.
    rank : ndarray of int, (N,)
        Rank by response within the keypoint's cell (0: the cell's strongest): the first
        keypoints of every cell are a well spread subset.
    descriptors : ndarray of float32, (N, 128)
        SIFT descriptors.
    """

    row: np.ndarray
    col: np.ndarray
    response: np.ndarray
    rank: np.ndarray
    descriptors: np.ndarray

    def __len__(self) -> int:
        return int(self.row.size)

    def subset(self, index: Any) -> Keypoints:
        """The keypoints selected by ``index`` (a boolean mask or integer indices)."""
        return Keypoints(self.row[index], self.col[index], self.response[index],
                         self.rank[index], self.descriptors[index])

    @classmethod
    def empty(cls) -> Keypoints:
        """No keypoint."""
        z = np.zeros(0)
        return cls(z, z, z, np.zeros(0, np.intp), np.zeros((0, 128), np.float32))


def to_uint8(pixels: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """``pixels`` stretched linearly to 8 bits between the 0.5th and 99.5th percentiles of the
    valid ones (SIFT's input).

    Parameters
    ----------
    pixels : ndarray, (R, C)
        Any real dtype.
    valid : ndarray of bool, (R, C), optional
        The pixels that count for the percentiles (default: the finite ones).

    Returns
    -------
    ndarray of uint8, (R, C)
        0 where not valid.
    """
    data = np.asarray(pixels, dtype=np.float32)
    ok = np.isfinite(data) if valid is None else (valid & np.isfinite(data))
    out = np.zeros(data.shape, np.uint8)
    if not ok.any():
        return out
    lo, hi = np.percentile(data[ok], STRETCH_PERCENTILES)
    scale = 255.0 / max(float(hi - lo), 1e-6)
    out[ok] = np.clip(np.rint((data[ok] - lo) * scale), 0, 255).astype(np.uint8)
    return out


def _valid_mask(pixels: np.ndarray, nodata: float | None) -> np.ndarray:
    """Pixels with data, shrunk by :data:`NODATA_MARGIN_PX` around those without."""
    valid = np.isfinite(pixels)
    if nodata is not None and math.isfinite(nodata):
        valid &= pixels != nodata
    if valid.all():
        return valid
    import cv2

    k = 2 * NODATA_MARGIN_PX + 1
    return cv2.erode(valid.astype(np.uint8), np.ones((k, k), np.uint8)).astype(bool)


def _detect_chunk(sift: Any, pixels: np.ndarray, nodata: float | None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SIFT on one chunk: ``(N, 2)`` (row, col), ``(N,)`` response, ``(N, 128)`` descriptors."""
    import cv2

    valid = _valid_mask(pixels, nodata)
    if not valid.any():
        return np.zeros((0, 2)), np.zeros(0), np.zeros((0, 128), np.float32)
    image = to_uint8(pixels, valid)
    found, desc = sift.detectAndCompute(image, valid.astype(np.uint8))
    if not found or desc is None:
        return np.zeros((0, 2)), np.zeros(0), np.zeros((0, 128), np.float32)
    xy = np.asarray(cv2.KeyPoint_convert(found), dtype=np.float64)  # type: ignore[attr-defined]
    xy = xy.reshape(-1, 2)
    # the response has no array accessor in OpenCV's Python API: one attribute per keypoint
    response = np.fromiter((k.response for k in found), dtype=float, count=len(found))
    return xy[:, ::-1].copy(), response, np.asarray(desc, np.float32)


def detect_keypoints(
    image: OpenedImage,
    window: tuple[int, int, int, int] | None = None,
    *,
    max_keypoints: int = 20000,
    cell_px: int = 128,
    chunk_px: int = 2048,
    contrast_threshold: float = 0.02,
) -> Keypoints:
    """SIFT keypoints of a window of an image, spread over it.

    Parameters
    ----------
    image : ImageSource or ArrayImage
        From :func:`geoblock.io.open_image`; its first band is used.
    window : (row_start, row_stop, col_start, col_stop), optional
        Pixels of the image to search (clipped to it); default the whole image.
    max_keypoints : int
        Cap on the keypoints kept over the window; each ``cell_px`` cell keeps at most its
        share (by area), the strongest first.
    cell_px : int
        Side of the cells the cap is shared over, pixels.
    chunk_px : int
        Side of the chunks SIFT runs on (memory: about 60 bytes per pixel of a chunk).
    contrast_threshold : float
        SIFT's ``contrastThreshold`` (OpenCV's default 0.04; lower finds more keypoints in
        low-contrast areas).

    Returns
    -------
    Keypoints
        Sorted by cell, then by decreasing response.

    Raises
    ------
    MatchError
        An option out of range (names it).
    """
    import cv2

    for name, value in (("max_keypoints", max_keypoints), ("cell_px", cell_px),
                        ("chunk_px", chunk_px)):
        if int(value) < 1:
            raise MatchError(f"detect_keypoints: {name} must be >= 1, got {value!r}")
    if not (math.isfinite(contrast_threshold) and contrast_threshold > 0):
        raise MatchError(f"detect_keypoints: contrast_threshold must be > 0, got "
                         f"{contrast_threshold!r}")
    rows, cols = (int(v) for v in image.shape)
    r0, r1, c0, c1 = (0, rows, 0, cols) if window is None else (int(v) for v in window)
    r0, c0 = max(r0, 0), max(c0, 0)
    r1, c1 = min(r1, rows), min(c1, cols)
    if r1 <= r0 or c1 <= c0:
        return Keypoints.empty()
    sift = cv2.SIFT_create(  # type: ignore[attr-defined]
        contrastThreshold=float(contrast_threshold))
    nodata = image.nodata
    geometry, response, descriptors = [], [], []
    m = CHUNK_MARGIN_PX
    for cr in range(r0, r1, chunk_px):  # chunks, not points: a handful of SIFT calls
        for cc in range(c0, c1, chunk_px):
            core = (cr, min(cr + chunk_px, r1), cc, min(cc + chunk_px, c1))
            read = (max(core[0] - m, 0), min(core[1] + m, rows),
                    max(core[2] - m, 0), min(core[3] + m, cols))
            pixels = image.read(read)[0].astype(np.float32)
            g, resp, desc = _detect_chunk(sift, pixels, nodata)
            g[:, 0] += read[0]
            g[:, 1] += read[2]
            inside = ((g[:, 0] >= core[0] - 0.5) & (g[:, 0] < core[1] - 0.5)
                      & (g[:, 1] >= core[2] - 0.5) & (g[:, 1] < core[3] - 0.5))
            geometry.append(g[inside])
            response.append(resp[inside])
            descriptors.append(desc[inside])
    g = np.concatenate(geometry)
    resp = np.concatenate(response)
    desc = np.concatenate(descriptors)
    if not resp.size:
        return Keypoints.empty()
    # spread: each cell keeps its share of max_keypoints, strongest first
    n_cr = max(1, math.ceil((r1 - r0) / cell_px))
    n_cc = max(1, math.ceil((c1 - c0) / cell_px))
    cell_r = np.clip(((g[:, 0] - r0 + 0.5) // cell_px).astype(np.intp), 0, n_cr - 1)
    cell_c = np.clip(((g[:, 1] - c0 + 0.5) // cell_px).astype(np.intp), 0, n_cc - 1)
    cell = cell_r * n_cc + cell_c
    # ties of response broken by position, not by the order OpenCV's threads found them in
    # (the keypoints' indices number the tie points: they must not depend on the schedule)
    order = np.lexsort((g[:, 1], g[:, 0], -resp, cell))
    cell = cell[order]
    first = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
    starts = np.repeat(first, np.diff(np.r_[first, cell.size]))
    rank = np.arange(cell.size) - starts
    per_cell = max(1, math.ceil(max_keypoints / (n_cr * n_cc)))
    keep = order[rank < per_cell]
    rank = rank[rank < per_cell]
    return Keypoints(g[keep, 0], g[keep, 1], resp[keep], rank, desc[keep])
