"""Islands: a block's image graph and its components, checked before solving."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock.adjust import Block, adjust
from geoblock.adjust._islands import block_components, check_block
from geoblock.errors import AdjustmentError, TooFewPointsError
from geoblock.testing.blocks import affine_block

A = ("img00", "img01")  # the west group of a 1 x 4 block
B = ("img02", "img03")


def split_block(seed: int = 5, gcps: int = 6):
    """A 1 x 4 affine block whose tie points across img01 | img02 are removed: two groups."""
    sb = affine_block((1, 4), gcps=gcps, icps=2, tps=200, ictps=0, seed=seed)
    m = sb.block.measurements
    in_a = np.isin(m.image, A)
    ids = np.unique(m.id)
    pos = np.searchsorted(ids, m.id)
    side_a = np.bincount(pos, weights=in_a, minlength=ids.size) > 0
    side_b = np.bincount(pos, weights=~in_a, minlength=ids.size) > 0
    across = (side_a & side_b)[pos] & np.isin(m.kind, ("tp", "gcp"))
    assert across.any()  # the cut removes something
    block = Block(sb.block.models, m.subset(~across), sb.block.ground, sb.block.dem,
                  sb.block.dem_sigma_m)
    return sb, block


def test_a_connected_block_is_one_component():
    sb = affine_block((2, 2), gcps=2, icps=0, tps=100, ictps=0, seed=3)
    conn = block_components(sb.block)
    assert conn.n_components == 1
    assert conn.links >= 4  # the four neighbours at least (diagonals share TPs too)
    assert check_block(sb.block, "refuse") == [sb.block.image_ids]


def test_two_groups_are_refused_before_solving_naming_both(monkeypatch):
    _, block = split_block()
    conn = block_components(block)
    assert conn.n_components == 2
    assert sorted(conn.groups()) == [A, B]
    # refused before any engine is built (no projection, no linearisation)
    import geoblock.adjust.block as block_module

    def no_engine(*args, **kwargs):
        raise AssertionError("an engine was built")

    monkeypatch.setattr(block_module, "_Engine", no_engine)
    with pytest.raises(AdjustmentError, match=r"2 disconnected groups.*img00, img01 \(2 "
                       r"images\).*img02, img03 \(2 images\).*components=\"separate\""):
        adjust(block)


def test_separate_components_adjust_each_group_as_alone():
    sb, block = split_block()
    result = adjust(block, components="separate")
    assert result.converged
    assert any("2 disconnected groups" in n for n in result.notes)
    # each group's answer is the one of the group adjusted on its own
    for group in (A, B):
        keep = np.isin(block.measurements.image, group)
        alone = adjust(Block({i: block.models[i] for i in group},
                             block.measurements.subset(keep), block.ground, block.dem,
                             block.dem_sigma_m))
        for image in group:
            np.testing.assert_allclose(result.parameters[image].values,
                                       alone.parameters[image].values, rtol=0, atol=1e-9)
            np.testing.assert_allclose(result.parameters[image].sigmas,
                                       alone.parameters[image].sigmas, rtol=1e-9)
    # the covariance holds no term across the groups
    index = result.parameter_index
    in_a = np.array([img in A for img, _ in index])
    assert np.all(result.covariance[np.ix_(in_a, ~in_a)] == 0)
    assert np.all(np.diag(result.covariance) > 0)
    # the joint solution (one system) gives the same estimates
    joint = adjust(block, components="joint")
    for image in A + B:
        np.testing.assert_allclose(joint.parameters[image].values,
                                   result.parameters[image].values, rtol=0, atol=1e-6)


def test_images_without_enough_points_are_all_named():
    sb = affine_block((1, 3), gcps=2, icps=0, tps=100, ictps=0, seed=9)
    models = dict(sb.block.models)
    models["lonely"] = models["img00"]
    models["alone"] = models["img01"]
    with pytest.raises(TooFewPointsError, match=r"2 image\(s\) without enough points.*"
                       r"lonely \(0 measurement.*alone \(0 measurement"):
        adjust(Block(models, sb.block.measurements, sb.block.ground, sb.block.dem))


def test_unknown_components_option_is_refused():
    sb = affine_block((1, 2), gcps=2, icps=0, tps=20, ictps=0, seed=2)
    with pytest.raises(AdjustmentError, match="components must be one of"):
        adjust(sb.block, components="merge")


def test_the_graph_is_fast_on_a_large_block():
    """10^4 images in a chain, 10^6 measurements: the graph's components and links (its
    time is in benchmarks/README.md, not asserted here)."""
    n_img, per = 10_000, 100
    rng = np.random.default_rng(0)
    image = np.repeat(np.arange(n_img), per)
    # each point measured in an image and its successor (a chain), one cut at 5000
    pts = np.arange(n_img * per // 2)
    first = pts // (per // 2)
    keep = (first < n_img - 1) & (first != 4999)
    pts, first = pts[keep], first[keep]
    from geoblock.adjust import _islands

    label, links = _islands._components(
        np.concatenate([first, first + 1]), np.concatenate([pts, pts]), n_img)
    assert np.unique(label).size == 2
    assert np.all(label[:5000] == label[0]) and np.all(label[5000:] == label[5000])
    assert links == n_img - 2
    del image, rng
