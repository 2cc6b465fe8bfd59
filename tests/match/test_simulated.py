"""``geoblock match`` on simulated images whose truth is known (tests/match/conftest.py): the
images are rendered through TRUE models over the TRUE terrain; the matcher is given the
ON-BOARD models (off by 20-30 m, 8-12 px) and a measured DEM (RMSEz 5 m)."""

from __future__ import annotations

import numpy as np
import pytest

import geoblock
from geoblock.errors import BlockFileError, CropError, MatchError
from geoblock.io import read_points
from geoblock.io.images import ArrayImage
from geoblock.io.points import read_observations
from geoblock.match import MatchImage, MatchOptions, match_block, match_images
from geoblock.match.consistency import consistent, scale_of
from geoblock.match.geometry import predict

PAIRS = (("a", "b"), ("a", "c"), ("b", "c"))


@pytest.fixture(scope="module")
def matched(triplet):
    outdir, _ = triplet
    messages = []
    return match_block(outdir / "block.toml", progress=messages.append), messages


def test_kept_matches_are_within_a_pixel_of_the_truth(triplet, matched):
    _, truth = triplet
    tps, messages = matched
    for a, b in PAIRS:
        err = truth.errors(tps, a, b)
        # kept per pair: 153-230 with bias-drift on-board errors, 138-199 with the realistic
        # ones of issue 27 (a measured attitude wander and a look-angle error in the true
        # models the images are rendered with: other images, 365-542 candidates instead of
        # 405-506, the same share of rejections)
        assert err.size >= 130, (a, b, err.size)
        within = float(np.mean(err < 1.0))
        assert within >= 0.95, (a, b, within, np.percentile(err, [50, 90, 99]))
        assert np.median(err) < 0.35, (a, b, np.median(err))
    # every pair found the models' disagreement (8-25 px) and said so
    assert sum("models' offset" in m for m in messages) >= 3
    for pair in tps.pairs:
        assert pair.counts()["kept"] >= 130
        # the offset said is the on-board models' true disagreement where the pair matched:
        # the truth's position in B minus the on-board prediction, averaged over the matches
        keep = pair.kept
        r, c = truth.transfer(pair.image_a, pair.image_b, pair.row_a[keep], pair.col_a[keep])
        true_offset = np.mean(r - pair.pred_row[keep]), np.mean(c - pair.pred_col[keep])
        assert np.hypot(*true_offset) > 3.0, true_offset
        said = pair.offset_px()
        assert np.hypot(said[0] - true_offset[0], said[1] - true_offset[1]) < 0.2, (
            said, true_offset)
        assert f"models' offset {said[0]:+.2f}, {said[1]:+.2f} px" in pair.summary()
    assert "matches/s" in tps.summary()


def test_points_seen_in_three_images_have_one_id(matched):
    tps, _ = matched
    ids, counts = np.unique(tps.id, return_counts=True)
    assert (counts <= 3).all() and (counts == 3).sum() >= 50
    # one measurement per image and id; ids numbered from tp00000, sorted by id then image
    keys = np.char.add(np.char.add(tps.id, "/"), tps.image)
    assert np.unique(keys).size == keys.size
    assert tps.id[0] == "tp00000" and (tps.id[:-1] <= tps.id[1:]).all()
    assert tps.n_points == ids.size


def test_the_csv_reads_back_into_the_block_engine(matched, tmp_path):
    tps, _ = matched
    path = tmp_path / "tp.csv"
    geoblock.io.write_points(path, tps.to_columns())
    header = path.read_text().splitlines()[0]
    assert header == "id,image,row,col,sigma,kind"
    _, points = read_observations(None, path)
    assert len(points) == len(tps)
    assert set(points.kind.tolist()) == {"tp"}
    assert np.array_equal(points.row, tps.row) and np.array_equal(points.sigma_col, tps.sigma)
    assert (tps.sigma > 0).all() and (tps.sigma < 0.5).all()
    direct = tps.image_points()
    assert np.array_equal(direct.id, points.id)


def test_wrong_matches_injected_into_real_geometry_are_rejected(triplet, matched):
    """The kept matches of a & b, with 30 moved 1.5-4 px across their epipolar line and 30
    moved by 40-60 m of height along it (a few pixels: a homography would keep them)."""
    outdir, _ = triplet
    tps, _ = matched
    pair = tps.pairs[0]
    keep = pair.kept
    models = {i: geoblock.open_model(outdir / "images" / f"{i}_onboard.json") for i in "ab"}
    dem = geoblock.open_dem(outdir / "terrain" / "dem.tif")
    ra, ca = pair.row_a[keep], pair.col_a[keep]
    p = predict(models["a"], models["b"], dem, ra, ca)
    d_row, d_col = pair.row_b[keep] - p.row, pair.col_b[keep] - p.col
    e = np.stack([p.epi_row, p.epi_col], axis=-1)
    u = e / np.linalg.norm(e, axis=1, keepdims=True)
    rng = np.random.default_rng(0)
    across, along = np.arange(30), np.arange(30, 60)
    push = rng.uniform(1.5, 4.0, 30) * rng.choice([-1, 1], 30)
    d_row[across] -= push * u[across, 1]
    d_col[across] += push * u[across, 0]
    lift = rng.uniform(40.0, 60.0, 30) * rng.choice([-1, 1], 30)
    d_row[along] += lift * e[along, 0]
    d_col[along] += lift * e[along, 1]
    assert np.hypot(lift * e[along, 0], lift * e[along, 1]).max() < 12.0
    centre, scale = scale_of(models["a"].shape)
    out = consistent(ra, ca, d_row, d_col, p.epi_row, p.epi_col, np.ones(ra.size, bool),
                     centre=centre, scale=scale)
    assert out.epipolar[across].all()
    assert (out.epipolar | out.height)[along].all()
    assert out.inlier[60:].mean() > 0.9


def test_command_line_pair_with_model_files(triplet, tmp_path):
    from click.testing import CliRunner

    from geoblock.cli.main import build_cli

    outdir, truth = triplet
    images = outdir / "images"
    out = tmp_path / "tp.csv"
    diag = tmp_path / "diag.csv"
    result = CliRunner().invoke(build_cli(), [
        "match", str(images / "a.tif"), str(images / "b.tif"),
        "--model", str(images / "a_onboard.json"), "--model", str(images / "b_onboard.json"),
        "--dem", str(outdir / "terrain" / "dem.tif"), "-o", str(out),
        "--diagnostics", str(diag)])
    assert result.exit_code == 0, result.output
    assert "tie points" in result.stderr and "matches/s" in result.stderr
    assert "a & b:" in result.stderr
    table = read_points(out)
    assert set(table["image"].tolist()) == {"a", "b"}  # the file names without extension
    err = truth.errors(table, "a", "b")
    assert np.mean(err < 1.0) >= 0.95
    d = read_points(diag, required=("row_b", "pred_row", "offset_row", "row_a", "col_a"))
    kept = d["status"] == "kept"
    # one tie point per kept match, but for the few whose keypoint shares its position with
    # another keypoint of its image (SIFT's second orientation) matched elsewhere: one point
    # matched to two places, dropped as contradictory; never two ids at one image position
    in_a = table["image"] == "a"
    csv_a = set(zip(np.round(table["row"][in_a], 3).tolist(),
                    np.round(table["col"][in_a], 3).tolist(), strict=True))  # as written
    found = np.array([(r, c) in csv_a for r, c in zip(np.round(d["row_a"][kept], 3).tolist(),
                                                       np.round(d["col_a"][kept], 3).tolist(),
                                                       strict=True)])
    assert found.sum() == np.unique(table["id"]).size
    assert (~found).sum() <= 0.05 * kept.sum()
    for image in ("a", "b"):
        here = table["image"] == image
        at = np.column_stack([table["row"][here], table["col"][here]])
        assert np.unique(at, axis=0).shape[0] == here.sum()
    assert set(d["status"].tolist()) <= {"kept", "ratio", "unique", "correlation", "epipolar",
                                         "height"}
    # offsets are match minus prediction
    assert np.allclose(d["offset_row"], d["row_b"] - d["pred_row"])


def test_errors_name_the_files(triplet, tmp_path):
    from geoblock.testing.synthetic import AffineCamera

    outdir, _ = triplet
    images = outdir / "images"
    dem = geoblock.open_dem(outdir / "terrain" / "dem.tif")
    a = MatchImage.from_files("a", images / "a.tif", images / "a_onboard.json")
    # a model of somewhere else: no overlap
    far = AffineCamera.example()
    rows, cols = far.shape
    elsewhere = MatchImage("far", ArrayImage(np.zeros((rows, cols), np.uint8), name="far.tif"),
                           far)
    # ... on a DEM that covers a but not far: said, per image
    with pytest.raises(MatchError, match="DEM cannot place.*far.tif: the DEM has no valid "
                       "height over the scene") as err:
        match_images([a, elsewhere], dem)
    assert "a.tif" not in str(err.value)
    # ... on a DEM that covers both
    with pytest.raises(MatchError, match="no two of the images overlap.*far.tif"):
        match_images([a, elsewhere], geoblock.dem.ConstantDem(200.0))
    # an image without texture where it overlaps
    b_model = geoblock.open_model(images / "b_onboard.json")
    flat = MatchImage("flat", ArrayImage(np.full(b_model.shape, 100, np.uint8),
                                         name="flat.tif"), b_model)
    with pytest.raises(MatchError, match="flat.tif: no SIFT keypoint"):
        match_images([a, flat], dem)
    # a model that does not fit the image (another shape, no crop offset)
    small = tmp_path / "small.tif"
    geoblock.io.write_image(small, np.ones((100, 120), np.uint8))
    with pytest.raises(CropError, match="small.tif"):
        MatchImage.from_files("small", small, images / "b_onboard.json")
    with pytest.raises(MatchError, match="at least two"):
        match_images([a], dem)
    with pytest.raises(MatchError, match="duplicate image id"):
        match_images([a, a], dem)
    with pytest.raises(MatchError, match="ratio"):
        MatchOptions(ratio=1.5)


def test_a_block_without_rasters_is_refused(triplet, tmp_path):
    outdir, _ = triplet
    text = (outdir / "block.toml").read_text()
    text = "\n".join(line for line in text.splitlines() if not line.startswith("raster"))
    block = outdir / "no_rasters.toml"
    block.write_text(text)
    with pytest.raises(BlockFileError, match=r"images\[0\] \(a\).*raster"):
        match_block(block)
