"""``--ictp-share``: a share of the matched points written as ICTPs (Teo et al.'s independent
check tie points), every measurement of a point with the same kind, the same for the same
inputs."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.errors import MatchError
from geoblock.match.results import TiePoints


def _tie_points(n: int) -> TiePoints:
    ids = np.repeat([f"tp{k:05d}" for k in range(n)], 2)
    return TiePoints(id=ids, image=np.tile(["left", "right"], n), row=np.zeros(2 * n),
                     col=np.zeros(2 * n), sigma=np.full(2 * n, 0.2), pairs=(),
                     images=("left", "right"), keypoints={}, dropped_tracks=0, seconds=0.0)


def test_every_fifth_point_is_an_ictp_in_all_its_images():
    tp = _tie_points(100)
    kind = tp.to_columns(0.2)["kind"]
    assert set(kind) == {"tp", "ictp"}
    ictp_ids = np.unique(tp.id[kind == "ictp"])
    assert ictp_ids.size == 20
    # a point is an ICTP in every image or in none
    assert set(tp.id[kind == "tp"]).isdisjoint(ictp_ids)
    assert np.array_equal(tp.to_columns(0.2)["kind"], kind)  # deterministic
    assert (tp.to_columns()["kind"] == "tp").all()
    assert tp.image_points(0.2).kind.tolist() == kind.tolist()


@pytest.mark.parametrize("share", [-0.1, 0.6, float("nan")])
def test_a_share_outside_0_to_half_is_refused(share):
    with pytest.raises(MatchError, match="ictp_share"):
        _tie_points(10).kinds(share)
