"""Warm start: adding images to a solved block re-solves from the previous solution."""

from __future__ import annotations

import time

import numpy as np
import pytest

from geoblock.adjust import Block, adjust
from geoblock.errors import AdjustmentError
from geoblock.testing.blocks import affine_block

NEW = "img23"  # the image added to the solved block (1 of 12, about 10 %)


def without(block: Block, image: str) -> Block:
    """The block before ``image`` was added: its measurements dropped, and the tie points
    left in one image only with them."""
    m = block.measurements
    keep = m.image != image
    ids, pos = np.unique(m.id, return_inverse=True)
    rays = np.bincount(pos, weights=keep & (m.kind == "tp"), minlength=ids.size)
    keep &= (m.kind != "tp") | (rays[pos] >= 2)
    return Block({i: mo for i, mo in block.models.items() if i != image}, m.subset(keep),
                 block.ground, block.dem, block.dem_sigma_m)


@pytest.fixture(scope="module")
def case():
    sb = affine_block((3, 4), gcps=1, icps=2, tps=600, ictps=0, seed=17, error_px=60.0)
    before = adjust(without(sb.block, NEW), tolerance=1e-8)
    return sb.block, before


def test_adding_images_resolves_in_fewer_iterations_to_the_same_answer(case):
    block, before = case
    t0 = time.perf_counter()
    cold = adjust(block, tolerance=1e-8)
    t1 = time.perf_counter()
    warm = adjust(block, tolerance=1e-8, start=before)
    t2 = time.perf_counter()
    assert cold.converged and warm.converged
    assert warm.iterations < cold.iterations, (warm.iterations, cold.iterations)
    for image, est in cold.parameters.items():
        diff = np.abs(warm.parameters[image].values - est.values) / est.sigmas
        assert np.all(diff < 1e-6), (image, diff.max())
    assert any("warm start from a previous solution: 11 of 12 images" in n
               for n in warm.notes)
    print(f"cold {cold.iterations} iterations {t1 - t0:.2f} s, warm {warm.iterations} "
          f"iterations {t2 - t1:.2f} s")


def test_the_start_from_the_written_output_is_the_result(case, tmp_path):
    from geoblock.report.adjustment import write_result

    block, before = case
    write_result(before, tmp_path / "adj", figures=False)
    a = adjust(block, tolerance=1e-8, start=before)
    b = adjust(block, tolerance=1e-8, start=tmp_path / "adj")
    assert b.iterations == a.iterations
    for image, est in a.parameters.items():
        np.testing.assert_allclose(b.parameters[image].values, est.values, rtol=0,
                                   atol=1e-6 * est.sigmas.max())


def test_a_start_that_is_not_a_solution_is_refused(case, tmp_path):
    block, _ = case
    with pytest.raises(AdjustmentError, match="not a geoblock adjust output"):
        adjust(block, start=tmp_path)
    with pytest.raises(AdjustmentError, match="start must be a BlockResult"):
        adjust(block, start=42)
