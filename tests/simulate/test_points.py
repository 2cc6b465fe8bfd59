"""Simulated GCP/ICP/TP/ICTP: exact truth through the true models, designs, overlaps, noise,
blunders and the CSV files (read back by geoblock.io.read_points)."""

from __future__ import annotations

import numpy as np
import pytest

from geoblock import coords
from geoblock.errors import GeoblockError
from geoblock.io import read_points
from geoblock.simulate.points import simulate_points
from geoblock.simulate.terrain import Grid, ridged_terrain
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

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
