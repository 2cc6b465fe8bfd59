"""join_tracks: matches sharing a keypoint are one tie point, whatever the keypoint's index."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from geoblock.match.tracks import join_tracks


def _pair(index_a, index_b, pos_a, pos_b):
    pos_a = np.asarray(pos_a, float)
    pos_b = np.asarray(pos_b, float)
    return SimpleNamespace(kept=np.ones(len(index_a), bool), index_a=np.asarray(index_a),
                           index_b=np.asarray(index_b), row_a=pos_a[:, 0], col_a=pos_a[:, 1],
                           row_b=pos_b[:, 0], col_b=pos_b[:, 1])


def _join(results, pair_index, positions_b):
    images = [SimpleNamespace(id=name, offset=(0.0, 0.0)) for name in ("a", "b", "c")]
    options = SimpleNamespace(id_prefix="tp")
    return join_tracks(images, [5, 5, 5], results, pair_index, options, [0.3] * len(results),
                       lambda jobs: [(j[4], j[5], np.ones(j[4].size, bool)) for j in jobs],
                       positions_b)


def test_two_keypoints_at_one_position_are_one_tie_point():
    """SIFT's second orientation: keypoints 1 and 2 of image a are at one position; a & b
    matched keypoint 1, a & c keypoint 2. One tie point in three images, not two tie points
    measured at the same position of a (refused by the adjustment as coincident)."""
    here = [[10.5, 20.25]]
    ab = _pair([1], [3], here, [[11.0, 21.0]])
    ac = _pair([2], [4], here, [[12.0, 22.0]])
    out, dropped = _join([ab, ac], [(0, 1), (0, 2)], [([11.0], [21.0]), ([12.0], [22.0])])
    assert dropped == 0
    assert set(out["id"].tolist()) == {"tp00000"}
    assert sorted(out["image"].tolist()) == ["a", "b", "c"]
    positions = set(zip(out["image"].tolist(), out["row"].tolist(), out["col"].tolist()))
    assert len(positions) == 3


def test_keypoints_at_different_positions_stay_apart():
    ab = _pair([1], [3], [[10.5, 20.25]], [[11.0, 21.0]])
    ac = _pair([2], [4], [[30.5, 40.25]], [[12.0, 22.0]])
    out, _ = _join([ab, ac], [(0, 1), (0, 2)], [([11.0], [21.0]), ([12.0], [22.0])])
    assert len(set(out["id"].tolist())) == 2
