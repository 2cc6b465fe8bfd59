"""Matching as tasks (:mod:`geoblock.match.tasks`): the same CSV, byte for byte, on every
scheduler, whatever order the tasks finish in; the tiled refinement equals the whole-image
one."""

from __future__ import annotations

import hashlib
import time

import numpy as np
import pytest

from geoblock.errors import MatchError
from geoblock.match import MatchImage, MatchOptions, match_block, write_tie_points
from geoblock.match.geometry import local_affine
from geoblock.match.tasks import refine_in_tiles, run_tasks


def _sha256(tps, path):
    write_tie_points(path, tps)
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def reference(triplet, tmp_path_factory):
    """The triplet matched on the synchronous scheduler: its tie points and CSV's sha256."""
    outdir, _ = triplet
    messages = []
    tps = match_block(outdir / "block.toml", scheduler="synchronous", progress=messages.append)
    return tps, _sha256(tps, tmp_path_factory.mktemp("sync") / "tp.csv"), messages


@pytest.mark.parametrize("scheduler", ["threads", "processes"])
def test_local_schedulers_write_the_same_csv(triplet, reference, scheduler, tmp_path):
    outdir, _ = triplet
    tps = match_block(outdir / "block.toml", scheduler=scheduler)
    assert _sha256(tps, tmp_path / "tp.csv") == reference[1]
    assert len(tps) == len(reference[0]) > 500


def test_a_two_worker_local_cluster_writes_the_same_csv(triplet, reference, tmp_path):
    distributed = pytest.importorskip("distributed")
    outdir, _ = triplet
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        tps = match_block(outdir / "block.toml", scheduler=client)
    assert _sha256(tps, tmp_path / "tp.csv") == reference[1]


def test_progress_is_reported_as_pairs_complete(reference):
    _, _, messages = reference
    text = "\n".join(messages)
    # the pair graph before any matching, then each pair as it completes
    assert text.index("pair graph: 3 images") < text.index("matching 3 pairs")
    done = [m for m in messages if m.lstrip().startswith("[")]
    assert [m.split("]")[0].strip() for m in done] == ["[1/3", "[2/3", "[3/3"]


def test_results_come_back_in_the_tasks_order_whatever_order_they_finish():
    import dask

    def slow(k):
        time.sleep(0.05 * (3 - k))
        return k

    tasks = {f"t{k}": dask.delayed(slow, pure=False)(k, dask_key_name=f"slow-{k}")
             for k in range(3)}
    finished = []
    out = run_tasks(tasks, "threads", lambda name, value: finished.append(name))
    assert list(out) == ["t0", "t1", "t2"] and list(out.values()) == [0, 1, 2]
    assert finished == ["t2", "t1", "t0"]  # the last-submitted finished first
    with pytest.raises(MatchError, match="'thread' is none of threads"):
        run_tasks(tasks, "thread")


def test_refinement_in_tiles_equals_the_refinement_of_whole_images(triplet, reference):
    outdir, _ = triplet
    tps = reference[0]
    pair = tps.pairs[0]
    keep = pair.kept
    images = outdir / "images"
    a = MatchImage.from_files("a", images / "a.tif", images / "a_onboard.json")
    b = MatchImage.from_files("b", images / "b.tif", images / "b_onboard.json")
    from geoblock.io.blocks import read_block

    dem = read_block(outdir / "block.toml").dem.to_source()
    ra, ca = pair.row_a[keep], pair.col_a[keep]
    # start half a pixel off the match, so that the refinement has work to do
    rb, cb = pair.row_b[keep] + 0.5, pair.col_b[keep] - 0.5
    jac = local_affine(a.model, b.model, dem, ra, ca)
    opts = MatchOptions()
    whole = refine_in_tiles(a, b, ra, ca, rb, cb, jac, opts, tile_px=100000)
    tiled = refine_in_tiles(a, b, ra, ca, rb, cb, jac, opts, tile_px=64)
    # the same up to the rounding of the windows' offsets (the tiles are the same on every
    # scheduler: the CSV's bytes do not depend on them)
    for w, t in zip(whole[:3], tiled[:3], strict=True):
        np.testing.assert_allclose(w, t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(whole[3], tiled[3])
    assert (whole[3] == 0).mean() > 0.9
    assert np.median(np.hypot(whole[0] - pair.row_b[keep], whole[1] - pair.col_b[keep])) < 0.1


def test_cli_scheduler_option(triplet, reference, tmp_path):
    from click.testing import CliRunner

    from geoblock.cli.main import build_cli

    outdir, _ = triplet
    out = tmp_path / "tp.csv"
    result = CliRunner().invoke(build_cli(), ["match", str(outdir / "block.toml"), "-o",
                                              str(out), "--scheduler", "synchronous"])
    assert result.exit_code == 0, result.output
    assert hashlib.sha256(out.read_bytes()).hexdigest() == reference[1]
    result = CliRunner().invoke(build_cli(), ["match", str(outdir / "block.toml"), "-o",
                                              str(tmp_path / "x.csv"), "--scheduler", "thread"])
    assert result.exit_code == 2 and "'thread' is none of threads" in result.output


def test_a_pair_that_fails_does_not_stop_the_others(triplet, tmp_path):
    import geoblock

    outdir, _ = triplet
    flat = tmp_path / "c_flat.tif"
    geoblock.io.write_image(flat, np.full((300, 300), 100, np.uint8))
    block = tmp_path / "block.toml"
    text = (outdir / "block.toml").read_text().replace('"images/c.tif"', f'"{flat}"')
    block.write_text(text.replace('"images/', f'"{outdir}/images/').replace(
        '"terrain/', f'"{outdir}/terrain/'))
    messages = []
    tps = match_block(block, scheduler="threads", progress=messages.append)
    assert [(a, b) for a, b, _ in tps.failed] == [("a", "c"), ("b", "c")]
    assert all(f"{flat}: no SIFT keypoint" in why for _, _, why in tps.failed)
    assert set(tps.image.tolist()) == {"a", "b"} and len(tps.pairs) == 1
    assert "2 of 3 pairs failed" in "\n".join(messages)
    assert "from 1 pair(s) (2 failed)" in tps.summary()


def test_real_models_and_dem_travel_to_workers(data_dir, tmp_path):
    """The Ventoux Pleiades crops (RPCs of the geoblock-rpc plugin, a crop of the scene) and
    SRTM with EGM96 heights: pickled as a process or a worker receives them, they predict
    the same; matched on threads, the CSV is the synchronous one's."""
    import pickle

    import geoblock
    from geoblock.match.geometry import predict

    pytest.importorskip("geoblock_rpc", reason="the Ventoux RPCs need the geoblock-rpc plugin")
    paths = [data_dir / f"shareloc/{kind}/phr_ventoux/{side}_image.{ext}"
             for side in ("left", "right") for kind, ext in (("image", "tif"), ("rpc", "geom"))]
    srtm = data_dir / "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    for path in [*paths, srtm]:
        if not path.exists():
            pytest.skip(f"real data not found: {path}")
    images = [MatchImage.from_files("left", paths[0], paths[1]),
              MatchImage.from_files("right", paths[2], paths[3])]
    dem = geoblock.open_dem(srtm, vertical="geoid")
    sent_images, sent_dem = pickle.loads(pickle.dumps((images, dem)))
    rows, cols = np.meshgrid(np.linspace(0, 499, 5), np.linspace(0, 499, 5))
    here = predict(images[0].model, images[1].model, dem, rows.ravel(), cols.ravel())
    there = predict(sent_images[0].model, sent_images[1].model, sent_dem, rows.ravel(),
                    cols.ravel())
    assert here.ok.sum() >= 5 and np.array_equal(here.ok, there.ok)
    np.testing.assert_array_equal(here.row, there.row)
    np.testing.assert_array_equal(here.col, there.col)
    assert sent_images[0].image.read((0, 8, 0, 8)).tolist() == \
        images[0].image.read((0, 8, 0, 8)).tolist()
    from geoblock.match import match_images

    digests = {_sha256(match_images(images, dem, scheduler=s), tmp_path / f"{s}.csv")
               for s in ("synchronous", "threads")}
    assert len(digests) == 1


def test_without_the_candidates_the_csv_and_the_counts_are_the_same(triplet, reference,
                                                                      tmp_path):
    outdir, _ = triplet
    tps = match_block(outdir / "block.toml", scheduler="threads",
                      options=MatchOptions(keep_candidates=False))
    assert _sha256(tps, tmp_path / "tp.csv") == reference[1]
    full = reference[0]
    assert tps.counts() == full.counts() and full.counts()["candidates"] > 1000
    for small, big in zip(tps.pairs, full.pairs, strict=True):
        assert small.counts() == big.counts()
        assert small.status.size == big.counts()["kept"] < big.status.size
        assert small.summary().rsplit(";", 1)[0] == big.summary().rsplit(";", 1)[0]
    assert len(tps.diagnostics()["status"]) == full.counts()["kept"]
