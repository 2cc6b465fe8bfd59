"""SIFT keypoints: spread over cells with a cap, away from nodata, from any pixel type."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from geoblock.errors import MatchError
from geoblock.io.images import ArrayImage
from geoblock.match.features import NODATA_MARGIN_PX, detect_keypoints, to_uint8


def texture(shape=(256, 256), seed=0):
    rng = np.random.default_rng(seed)
    return gaussian_filter(rng.normal(size=shape), 2.0)


def test_to_uint8_stretches_the_valid_pixels():
    data = np.array([[1000.0, 1100.0], [1200.0, 0.0]])
    out = to_uint8(data, data > 0)
    assert out.dtype == np.uint8
    assert out[1, 1] == 0 and out[0, 0] < 5 and out[1, 0] > 250


def test_keypoints_of_a_uint16_image_are_spread_and_capped():
    pixels = (texture() * 300 + 2000).astype(np.uint16)  # 12-bit-like values
    kp = detect_keypoints(ArrayImage(pixels))
    assert len(kp) > 200
    assert kp.descriptors.shape == (len(kp), 128) and kp.descriptors.dtype == np.float32
    assert (kp.row >= -0.5).all() and (kp.row < 255.5).all()
    # a cap of 8 over 4 cells of 128 px: at most 2 per cell, the strongest of each
    few = detect_keypoints(ArrayImage(pixels), max_keypoints=8, cell_px=128)
    cells = (few.row // 128).astype(int) * 2 + (few.col // 128).astype(int)
    assert len(few) == 8 and np.bincount(cells, minlength=4).tolist() == [2, 2, 2, 2]
    assert set(few.rank.tolist()) == {0, 1}
    for c in range(4):
        in_cell = (kp.row // 128).astype(int) * 2 + (kp.col // 128).astype(int) == c
        assert few.response[cells == c].max() == pytest.approx(kp.response[in_cell].max())


def test_chunks_give_the_same_keypoints_inside_them():
    image = ArrayImage(texture((300, 300)))
    whole = detect_keypoints(image)
    chunked = detect_keypoints(image, chunk_px=150)
    # the chunks see 48 px of their neighbours (and are stretched to 8 bits each on its own):
    # most keypoints are found again at the same place
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(np.column_stack([chunked.row, chunked.col])).query(
        np.column_stack([whole.row, whole.col]))
    assert (dist < 0.25).mean() > 0.75
    assert 0.8 < len(chunked) / len(whole) < 1.25


def test_no_keypoint_near_nodata_and_none_in_a_window_of_nodata():
    pixels = texture() * 50 + 100
    pixels[:, 128:] = 0.0
    kp = detect_keypoints(ArrayImage(pixels, nodata=0.0))
    assert len(kp) > 50
    assert (kp.col < 128 - NODATA_MARGIN_PX).all()
    assert len(detect_keypoints(ArrayImage(pixels, nodata=0.0), (0, 256, 140, 256))) == 0
    assert len(detect_keypoints(ArrayImage(np.full((64, 64), 5.0)))) == 0


def test_a_window_restricts_the_search():
    kp = detect_keypoints(ArrayImage(texture()), (50, 150, 100, 200))
    assert len(kp) > 10
    assert (kp.row >= 49.5).all() and (kp.row < 149.5).all()
    assert (kp.col >= 99.5).all() and (kp.col < 199.5).all()


def test_options_are_checked():
    with pytest.raises(MatchError, match="max_keypoints"):
        detect_keypoints(ArrayImage(texture((32, 32))), max_keypoints=0)
    with pytest.raises(MatchError, match="contrast_threshold"):
        detect_keypoints(ArrayImage(texture((32, 32))), contrast_threshold=-1.0)
