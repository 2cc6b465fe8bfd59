"""Simulated GCP/ICP/TP/ICTP: exact truth through the true models, designs, overlaps, noise,
blunders and the CSV files (read back by geoblock.io.read_points)."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock import coords
from geoblock.errors import GeoblockError
from geoblock.io import read_points
from geoblock.simulate.points import (
    CandidatePositions,
    candidate_positions,
    ground_candidates,
    measure_points,
    overlap_points,
    overlap_window,
    point_ids,
    pointing_noise,
    simulate_points,
    survey_noise,
)
from geoblock.simulate.terrain import Grid, ridged_terrain
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom
from geoblock.typing import GroundCoords

SHAPE = (400, 500)
GSD = 2.5


def strips(n=3, overlap=0.12):
    """``n`` parallel north-flying pushbroom strips, ``overlap`` of their width side by side."""
    rows, cols = SHAPE
    speed, height = 7000.0, 700e3
    period = GSD / speed
    out = {}
    for k in range(n):
        east = (k - (n - 1) / 2) * (1 - overlap) * cols * GSD
        out[f"strip{k + 1}"] = ConstantVelocityPushbroom(
            SHAPE, origin=(7.05, 43.70), position=(east, -speed * period * rows / 2, height),
            velocity=(0.0, speed, 0.0), line_period=period, ifov=GSD / height)
    return out


@pytest.fixture(scope="module")
def scene():
    terrain = ridged_terrain(Grid.around(7.05, 43.70, (5000.0, 2000.0), 10.0), (0.0, 1500.0),
                             max_slope_deg=50.0, seed=2)
    return strips(), terrain


@pytest.fixture(scope="module")
def noise_free(scene):
    models, terrain = scene
    return simulate_points(models, terrain, gcp=9, icp=5, tp=(13, 32), ictp=4, sigma_px=0.0,
                           sigma_e=0.0, sigma_n=0.0, sigma_h=0.0, seed=1)


def test_counts_ids_and_kinds(noise_free):
    ps = noise_free
    assert ps.images == ("strip1", "strip2", "strip3")
    assert ps.count("gcp") == 27 and ps.count("icp") == 15 and ps.count("ictp") == 8
    assert 26 <= ps.count("tp") <= 64  # two overlapping pairs, 13-32 each
    assert len(set(ps.ground.id.tolist())) == len(ps.ground)
    assert set(ps.image.id.tolist()) == set(ps.ground.id.tolist())  # every point is measured


def test_noise_free_points_lie_on_the_terrain_and_reproject_exactly(scene, noise_free):
    models, terrain = scene
    g, m = noise_free.ground, noise_free.image
    dem = terrain.to_dem()
    np.testing.assert_allclose(dem.height(g.lon_true, g.lat_true), g.h_true, atol=2e-3)
    index = {p: i for i, p in enumerate(g.id.tolist())}
    k = np.array([index[p] for p in m.id.tolist()])
    for name, model in models.items():
        sel = m.image == name
        row, col = model.project(g.lon_true[k[sel]], g.lat_true[k[sel]], g.h_true[k[sel]])
        np.testing.assert_allclose(row, m.row_true[sel], atol=1e-9)
        np.testing.assert_allclose(col, m.col_true[sel], atol=1e-9)
    np.testing.assert_array_equal(m.row, m.row_true)
    np.testing.assert_array_equal(m.col, m.col_true)
    surveyed = np.isin(g.kind, ("gcp", "icp"))
    np.testing.assert_allclose(g.lon[surveyed], g.lon_true[surveyed], atol=1e-12)
    np.testing.assert_allclose(g.h[surveyed], g.h_true[surveyed], atol=1e-6)
    assert np.isnan(g.lon[~surveyed]).all() and np.isnan(g.sigma_e[~surveyed]).all()


def test_tie_points_lie_in_both_footprints(scene, noise_free):
    models, _ = scene
    m = noise_free.image
    ties = np.isin(m.kind, ("tp", "ictp"))
    for pid in np.unique(m.id[ties]):
        images = set(m.image[m.id == pid].tolist())
        assert images in ({"strip1", "strip2"}, {"strip2", "strip3"}), (pid, images)
    rows, cols = SHAPE
    assert ((m.row_true >= -0.5) & (m.row_true < rows - 0.5)).all()
    assert ((m.col_true >= -0.5) & (m.col_true < cols - 0.5)).all()
    # in strip2 the tie points with strip1 are on its west edge, those with strip3 on its east
    s2 = ties & (m.image == "strip2")
    with_1 = np.isin(m.id, m.id[ties & (m.image == "strip1")])
    assert (m.col_true[s2 & with_1] < 0.15 * cols).all()
    assert (m.col_true[s2 & ~with_1] > 0.85 * cols).all()


def test_stratified_design_one_point_per_cell():
    model = AffineCamera.example((900, 1200))
    ps = simulate_points([model], 120.0, gcp=9, icp=45, tp=0, design="stratified", cells=3,
                         margin_px=0.0, sigma_px=0.0)
    m = ps.image
    for kind, per_cell in (("gcp", 1), ("icp", 5)):  # Aguilar et al.: 45 in a 3 x 3 grid
        sel = m.kind == kind
        ci = np.floor((m.row_true[sel] + 0.5) / 300).astype(int)
        cj = np.floor((m.col_true[sel] + 0.5) / 400).astype(int)
        counts = np.bincount(ci * 3 + cj, minlength=9)
        assert counts.tolist() == [per_cell] * 9
    # the random design does not (for this seed) fill every cell once
    rnd = simulate_points([model], 120.0, gcp=9, tp=0, design="random", sigma_px=0.0, seed=3)
    cells = (np.floor((rnd.image.row_true + 0.5) / 300) * 3
             + np.floor((rnd.image.col_true + 0.5) / 400)).astype(int)
    assert np.bincount(cells, minlength=9).max() > 1


def test_noise_statistics_and_blunders(scene):
    models, terrain = scene
    ps = simulate_points(models, terrain, gcp=40, icp=40, tp=30, sigma_px=0.5, sigma_e=3.0,
                         sigma_n=3.0, sigma_h=2.0, blunder_fraction=0.05, blunder_px=25.0,
                         ground_blunder_fraction=0.1, ground_blunder_m=50.0, seed=5)
    m, g = ps.image, ps.ground
    d = np.hypot(m.row - m.row_true, m.col - m.col_true)
    assert m.blunder.sum() == round(0.05 * len(m))
    assert (d[m.blunder] > 20).all()
    clean = ~m.blunder
    assert np.std((m.row - m.row_true)[clean]) == pytest.approx(0.5, rel=0.15)
    surveyed = np.isin(g.kind, ("gcp", "icp"))
    assert g.blunder.sum() == round(0.1 * surveyed.sum()) and not g.blunder[~surveyed].any()
    e, n, u = (np.empty(len(g)) for _ in range(3))
    for i in np.flatnonzero(surveyed):  # a test-side loop over points: the independent check
        frame = coords.LocalFrame(g.lon_true[i], g.lat_true[i], g.h_true[i])
        e[i], n[i], u[i] = (float(v) for v in frame.from_geodetic(g.lon[i], g.lat[i], g.h[i]))
    ok = surveyed & ~g.blunder
    assert np.std(e[ok]) == pytest.approx(3.0, rel=0.25)
    assert np.std(u[ok]) == pytest.approx(2.0, rel=0.25)
    assert (np.hypot(e, n)[g.blunder] > 40).all()
    assert np.all(np.abs(u[g.blunder]) < 10)  # ground blunders are horizontal


def test_same_seed_same_points(scene):
    models, terrain = scene
    a = simulate_points(models, terrain, gcp=4, tp=5, seed=9)
    b = simulate_points(models, terrain, gcp=4, tp=5, seed=9)
    np.testing.assert_array_equal(a.image.row, b.image.row)
    np.testing.assert_array_equal(a.ground.lon, b.ground.lon)


def test_files_read_back(tmp_path, noise_free):
    paths = noise_free.write(tmp_path, prefix="sim_")
    assert {p.name for p in paths.values()} == {"sim_ground.csv", "sim_image.csv", "sim_truth.csv"}
    ground = read_points(paths["ground"], required=("lon", "lat", "h"))
    assert list(ground) == ["id", "lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h", "kind"]
    assert set(ground["kind"].tolist()) == {"gcp", "icp"}
    sel = np.isin(noise_free.ground.kind, ("gcp", "icp"))
    np.testing.assert_array_equal(ground["lon"], noise_free.ground.lon[sel])  # exact text floats
    image = read_points(paths["image"], required=("row", "col"))
    assert list(image)[:5] == ["id", "image", "row", "col", "sigma"]
    np.testing.assert_array_equal(image["row"], noise_free.image.row)
    truth = read_points(paths["truth"], required=("row_true", "col_true", "lon_true", "lat_true",
                                                  "h_true"))
    np.testing.assert_array_equal(truth["row_true"], noise_free.image.row_true)
    assert truth["id"].tolist() == image["id"].tolist()


def test_errors(scene):
    models, terrain = scene
    with pytest.raises(GeoblockError, match="design must be"):
        simulate_points(models, terrain, design="grid")
    with pytest.raises(GeoblockError, match="sigma_px must be"):
        simulate_points(models, terrain, sigma_px=-1.0)
    far = ConstantVelocityPushbroom.example(SHAPE, roll=0.3)  # looks ~200 km away from the DEM
    with pytest.raises(GeoblockError, match="found 0 of the 1 GCPs of image 'image1' in cell 0"):
        simulate_points([far], terrain, gcp=9, tp=0)


def test_observations_feed_the_block_engine(scene, noise_free):
    from geoblock.adjust import Block, adjust

    models, terrain = scene
    ground, measurements = noise_free.observations()
    assert set(ground.kind) == {"gcp", "icp"} and len(measurements) == len(noise_free.image)
    assert set(measurements.kind) == {"gcp", "icp", "tp", "ictp"}
    # noise-free points through the true models: nothing to adjust, residuals ~0
    result = adjust(Block(models, measurements, ground, terrain.to_dem()), mode="single")
    assert np.nanmax(np.abs(result.check.row)) < 1e-3


# ---------------------------------------------------------------------------- the steps
def test_simulate_points_is_the_composition_of_the_steps(scene):
    """The steps called in order on one generator give exactly simulate_points' points."""
    models, terrain = scene
    dem = terrain.to_dem()
    expected = simulate_points(models, terrain, gcp=5, icp=3, tp=(4, 9), ictp=2, sigma_px=0.3,
                               sigma_e=2.0, sigma_n=2.0, sigma_h=1.0, blunder_fraction=0.1,
                               blunder_px=12.0, ground_blunder_fraction=0.2, seed=21)
    rng = np.random.default_rng(21)
    names = list(models)
    parts = []
    for i, name in enumerate(names):
        for kind, count in (("gcp", 5), ("icp", 3)):
            cand = candidate_positions(models[name].shape, count, rng=rng)
            parts.append((kind, ground_candidates(models[name], dem, cand), i))
    for i, j in ((0, 1), (0, 2), (1, 2)):
        window = overlap_window(models[names[i]], models[names[j]], dem.height_range(),
                                min_overlap=0.01)
        if window is None:
            continue
        n_tp, n_ictp = int(rng.integers(4, 10)), 2
        ties = overlap_points(models[names[i]], models[names[j]], dem, n_tp + n_ictp, window,
                              rng=rng)
        parts.append(("tp", GroundCoords(*(v[:n_tp] for v in ties)), i))
        parts.append(("ictp", GroundCoords(*(v[n_tp:] for v in ties)), i))
    truth = GroundCoords(*(np.concatenate([p[1][k] for p in parts]) for k in range(3)))
    kind = np.concatenate([np.full(p[1].lon.size, p[0]) for p in parts])
    home = np.concatenate([np.full(p[1].lon.size, p[2]) for p in parts])
    seen = measure_points(models, truth, dem, home)
    row, col, blunder = pointing_noise(seen.row, seen.col, sigma_px=0.3, blunder_fraction=0.1,
                                       blunder_px=12.0, rng=rng)
    survey, g_blunder = survey_noise(truth, sigma_e=2.0, sigma_n=2.0, sigma_h=1.0,
                                     surveyed=np.isin(kind, ("gcp", "icp")),
                                     blunder_fraction=0.2, rng=rng)
    g, m = expected.ground, expected.image
    np.testing.assert_array_equal(point_ids(kind), g.id)
    np.testing.assert_array_equal(kind, g.kind)
    for got, want in ((truth.lon, g.lon_true), (truth.h, g.h_true), (survey.lon, g.lon),
                      (survey.h, g.h), (g_blunder, g.blunder), (seen.row, m.row_true),
                      (row, m.row), (col, m.col), (blunder, m.blunder)):
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(point_ids(kind)[seen.point], m.id)
    np.testing.assert_array_equal(seen.image, m.image)


def test_candidate_positions_by_design():
    cand = candidate_positions((900, 1200), 14, cells=3, margin_px=20.0, rng=4)
    assert isinstance(cand, CandidatePositions)
    assert sum(cand.wanted.values()) == 14 and sorted(set(cand.wanted.values())) == [1, 2]
    ci = np.floor((cand.row + 0.5 - 20.0) / ((900 - 40) / 3)).astype(int)
    cj = np.floor((cand.col + 0.5 - 20.0) / ((1200 - 40) / 3)).astype(int)
    np.testing.assert_array_equal(ci * 3 + cj, cand.cell)  # each position in its own cell
    assert cand.row.min() >= 19.5 and cand.row.max() < 900 - 20.5
    per_cell = np.bincount(cand.cell)
    assert (per_cell == 4 * 2 + 4).all()  # factor x the most wanted, plus 4
    rnd = candidate_positions((900, 1200), 5, design="random", rng=4)
    assert rnd.wanted == {-1: 5} and (rnd.cell == -1).all() and rnd.row.size == 4 * 5 + 8
    # the same generator advances; the same seed repeats
    gen = np.random.default_rng(8)
    a, b = (candidate_positions((100, 100), 3, rng=gen) for _ in range(2))
    assert not np.array_equal(a.row, b.row)
    np.testing.assert_array_equal(candidate_positions((100, 100), 3, rng=8).row, a.row)
    with pytest.raises(GeoblockError, match="no room"):
        candidate_positions((30, 30), 1, margin_px=20.0)
    with pytest.raises(GeoblockError, match="design must be"):
        candidate_positions((30, 30), 1, design="grid")


def test_ground_candidates_lie_on_the_terrain_under_their_positions(scene):
    models, terrain = scene
    model, dem = models["strip2"], terrain.to_dem()
    cand = candidate_positions(model.shape, 9, rng=1)
    g = ground_candidates(model, dem, cand)
    assert g.lon.shape == (9,)
    np.testing.assert_allclose(dem.height(g.lon, g.lat), g.h, atol=2e-3)
    row, col = model.project(g.lon, g.lat, g.h)
    first = [np.flatnonzero(cand.cell == c)[0] for c in range(9)]  # first of each cell
    np.testing.assert_allclose(row, cand.row[first], atol=1e-6)
    np.testing.assert_allclose(col, cand.col[first], atol=1e-6)
    far = ConstantVelocityPushbroom.example(SHAPE, roll=0.3)
    with pytest.raises(GeoblockError, match="found 0 of the 1 GCPs in cell 0"):
        ground_candidates(far, dem, candidate_positions(SHAPE, 9, rng=1), what="GCPs")


def test_overlap_window_and_points(scene):
    models, terrain = scene
    s1, s2, s3 = models.values()
    dem = terrain.to_dem()
    heights = dem.height_range()
    r0, r1, c0, c1 = overlap_window(s2, s1, heights, margin_px=10.0)
    cols = SHAPE[1]
    assert 9.5 <= c0 and c1 < 0.2 * cols and r0 >= 9.5  # strip1 is west of strip2
    assert overlap_window(s1, s3, heights) is None  # 12 % overlaps: 1 and 3 do not meet
    assert overlap_window(s2, s1, heights, min_overlap=0.5) is None  # too small a share
    g = overlap_points(s2, s1, dem, 12, (r0, r1, c0, c1), rng=3)
    assert g.lon.shape == (12,)
    seen = measure_points({"s1": s1, "s2": s2}, g, dem, home=np.full(12, 1))
    assert np.bincount(seen.point, minlength=12).tolist() == [2] * 12  # both see each point
    assert overlap_points(s2, s1, dem, 0, (r0, r1, c0, c1)).lon.size == 0


def test_measure_points_drops_points_outside_or_hidden(scene):
    models, terrain = scene
    dem = terrain.to_dem()
    s1, s2 = models["strip1"], models["strip2"]
    g = ground_candidates(s2, dem, candidate_positions(SHAPE, 9, rng=2))
    # the same positions 200 m under the terrain: hidden from every image but their home
    under = GroundCoords(g.lon, g.lat, g.h - 200.0)
    pair = {"strip1": s1, "strip2": s2}
    on = measure_points(pair, g, dem)
    assert (on.image == "strip2").sum() == 9  # on the terrain: seen where they were drawn
    assert (np.diff(on.point) >= 0).all()  # sorted by point
    assert measure_points(pair, under, dem).point.size == 0  # hidden everywhere
    home = measure_points(pair, under, dem, home=np.full(9, 1))  # drawn in strip2
    assert set(home.image.tolist()) <= {"strip2"}
    assert home.point.tolist() == list(range(9))
    row, col = s2.project(*under)
    np.testing.assert_allclose(home.row, row[home.point], atol=1e-9)


def test_point_ids_number_each_kind():
    ids = point_ids(np.array(["gcp", "tp", "gcp", "ictp", "tp"]))
    assert ids.tolist() == ["gcp0001", "tp0001", "gcp0002", "ictp0001", "tp0002"]


def test_pointing_noise():
    row, col = np.zeros(4000), np.full(4000, 7.0)
    r, c, blunder = pointing_noise(row, col, sigma_px=0.0, blunder_fraction=0.25,
                                   blunder_px=6.0, rng=0)
    assert blunder.sum() == 1000
    np.testing.assert_allclose(np.hypot(r - row, c - col)[blunder], 6.0)
    assert (r[~blunder] == 0).all() and (c[~blunder] == 7.0).all()
    r, c, _ = pointing_noise(row, col, sigma_px=0.5, rng=1)
    assert np.std(r) == pytest.approx(0.5, rel=0.1) and np.std(c - 7.0) == pytest.approx(0.5,
                                                                                         rel=0.1)
    with pytest.raises(GeoblockError, match="sigma_px must be"):
        pointing_noise(row, col, sigma_px=-1.0)
    with pytest.raises(GeoblockError, match=r"blunder_fraction must be in \[0, 1\]"):
        pointing_noise(row, col, sigma_px=1.0, blunder_fraction=2.0)


def test_survey_noise():
    n = 2000
    truth = GroundCoords(np.full(n, 7.05), np.full(n, 43.7), np.full(n, 300.0))
    surveyed = np.arange(n) % 2 == 0
    g, blunder = survey_noise(truth, sigma_e=0.0, sigma_n=0.0, sigma_h=0.0, surveyed=surveyed,
                              blunder_fraction=0.1, blunder_m=30.0, rng=5)
    assert np.isnan(g.lon[~surveyed]).all() and not blunder[~surveyed].any()
    assert blunder.sum() == round(0.1 * surveyed.sum())
    frame = coords.LocalFrame(7.05, 43.7, 300.0)
    e, nn, u = frame.from_geodetic(g.lon[surveyed], g.lat[surveyed], g.h[surveyed])
    np.testing.assert_allclose(np.hypot(e, nn)[blunder[surveyed]], 30.0, rtol=1e-6)
    np.testing.assert_allclose(u, 0.0, atol=1e-3)  # horizontal blunders
    np.testing.assert_allclose(e[~blunder[surveyed]], 0.0, atol=1e-6)
    g, _ = survey_noise(truth, sigma_e=1.0, sigma_n=2.0, sigma_h=3.0, rng=6)
    e, nn, u = frame.from_geodetic(g.lon, g.lat, g.h)
    assert [np.std(e), np.std(nn), np.std(u)] == pytest.approx([1.0, 2.0, 3.0], rel=0.1)
