"""Large simulated blocks (geoblock.simulate.large) and the continental-spot-100 preset."""

from __future__ import annotations

import numpy as np
import pyproj
import pytest

from geoblock.errors import GeoblockError
from geoblock.simulate.large import (
    LARGE_PRESETS,
    LargeBlockSpec,
    large_block,
    large_preset,
    layout,
)
from geoblock.simulate.scenario import preset
from geoblock.typing import Status

GEOD = pyproj.Geod(ellps="WGS84")


@pytest.fixture(scope="module")
def small() -> object:
    spec = LargeBlockSpec(name="t", strips=3, scenes=4, tps=3000, gcps=20, icps=30, ictps=40,
                          seed=5)
    return large_block(spec)


def test_layout_steps_on_the_ellipsoid() -> None:
    spec = large_preset("continental-spot-1000")
    lay = layout(spec)
    assert lay.ids.size == 1000 and lay.ids[0] == "s000k000" and lay.ids[-1] == "s019k049"
    # neighbouring scenes of a strip and neighbouring strips: the asked distances (scale of
    # the oblique Mercator under 1 % within 500 km of its central line)
    i = np.flatnonzero((lay.strip == 10) & (lay.scene < 49))
    _, _, along = GEOD.inv(lay.lon[i], lay.lat[i], lay.lon[i + 1], lay.lat[i + 1])
    assert i.size == 49
    assert np.allclose(along, 60e3 * 0.9, rtol=0.01)
    j = np.flatnonzero((lay.strip < 19) & (lay.scene == 25))
    _, _, across = GEOD.inv(lay.lon[j], lay.lat[j], lay.lon[j + 50], lay.lat[j + 50])
    assert np.allclose(across, 60e3 * 0.75, rtol=0.01)
    # a continental extent: about 2700 km along track
    _, _, span = GEOD.inv(lay.lon[500], lay.lat[500], lay.lon[549], lay.lat[549])
    assert 2500e3 < span < 2800e3
    # one incidence per strip, within +-5 deg; epochs of a strip follow each other
    assert np.all(np.abs(lay.incidence_deg) <= 5.0)
    assert len(set(lay.incidence_deg[lay.strip == 3].tolist())) == 1
    assert lay.epoch[0] != lay.epoch[1]


def test_layout_beyond_the_orbit_is_refused() -> None:
    spec = LargeBlockSpec(name="polar", strips=2, scenes=60, tps=10, centre_lat=70.0)
    with pytest.raises(GeoblockError, match="latitude"):
        layout(spec)


def test_spec_validation() -> None:
    with pytest.raises(GeoblockError, match="side_overlap"):
        LargeBlockSpec(name="x", strips=2, scenes=2, tps=10, side_overlap=0.95)
    with pytest.raises(GeoblockError, match="tps"):
        LargeBlockSpec(name="x", strips=2, scenes=2, tps=-1)
    with pytest.raises(GeoblockError, match="method"):
        LargeBlockSpec(name="x", strips=2, scenes=2, tps=1, method="nope")
    with pytest.raises(GeoblockError, match="continental-spot-1000"):
        large_preset("nope")


def test_large_preset_scaling() -> None:
    assert set(LARGE_PRESETS) == {"continental-spot-1000", "continental-spot-10000"}
    assert LARGE_PRESETS["continental-spot-1000"].images == 1000
    assert LARGE_PRESETS["continental-spot-1000"].tps == 10**6
    assert LARGE_PRESETS["continental-spot-10000"].images == 10**4
    assert LARGE_PRESETS["continental-spot-10000"].tps == 2 * 10**6
    s = large_preset("continental-spot-1000", images=300, tps=3000, seed=3)
    assert abs(s.images - 300) <= 10 and s.tps == 3000 and s.seed == 3


def test_points_counts_and_visibility(small) -> None:
    pts = small.points
    assert [pts.count(k) for k in ("gcp", "icp", "tp", "ictp")] == [20, 30, 3000, 40]
    m = pts.image
    for kind, least in (("gcp", 1), ("icp", 1), ("tp", 2), ("ictp", 2)):
        _, n = np.unique(m.id[m.kind == kind], return_counts=True)
        assert n.min() >= least
    # some TPs tie three images or more (side and along-track overlaps cross)
    _, n = np.unique(m.id[m.kind == "tp"], return_counts=True)
    assert (n >= 3).any()
    assert set(m.image.tolist()) == set(small.layout.ids.tolist())


def test_measurements_are_the_true_projections(small) -> None:
    g, m = small.points.ground, small.points.image
    index = {p: i for i, p in enumerate(g.id.tolist())}
    k = np.array([index[p] for p in m.id.tolist()])
    for image in small.layout.ids.tolist():
        sel = m.image == image
        model = small.sensors[image].true_model
        (r, c), status = model.project_with_status(g.lon_true[k[sel]], g.lat_true[k[sel]],
                                                   g.h_true[k[sel]])
        assert np.all(status == Status.CONVERGED)
        assert np.allclose(r, m.row_true[sel], atol=1e-6)
        assert np.allclose(c, m.col_true[sel], atol=1e-6)
        rows, cols = model.shape
        assert np.all((r > 9) & (r < rows - 10) & (c > 9) & (c < cols - 10))
    # the points lie on the true terrain
    h = small.truth.to_dem().height(g.lon_true, g.lat_true)
    assert np.allclose(h, g.h_true, atol=1e-6)
    # pointing noise of the asked size
    d = np.concatenate([m.row - m.row_true, m.col - m.col_true])
    assert 0.25 < np.std(d) < 0.35


def test_every_visible_image_measures(small) -> None:
    """No image that sees a point is left out (the 3 x 3 neighbourhood search is enough)."""
    g, m = small.points.ground, small.points.image
    sel = np.flatnonzero(g.kind == "tp")[:500]
    for image in small.layout.ids.tolist():
        model = small.sensors[image].true_model
        (r, c), status = model.project_with_status(g.lon_true[sel], g.lat_true[sel],
                                                   g.h_true[sel])
        rows, cols = model.shape
        inside = (status == Status.CONVERGED) & (r >= 9.5) & (r < rows - 10.5) \
            & (c >= 9.5) & (c < cols - 10.5)
        measured = set(m.id[m.image == image].tolist())
        assert set(g.id[sel][inside].tolist()) <= measured


def test_deterministic() -> None:
    spec = LargeBlockSpec(name="d", strips=2, scenes=2, tps=200, gcps=4, icps=4, seed=9,
                          relief=(0.0, 800.0))
    a, b = large_block(spec), large_block(spec)
    assert np.array_equal(a.points.image.row, b.points.image.row)
    assert np.array_equal(a.points.ground.lon_true, b.points.ground.lon_true)
    c = large_block(spec.replace(seed=10))
    assert not np.array_equal(a.points.ground.lon_true[:10], c.points.ground.lon_true[:10])


def test_block_adjusts(small) -> None:
    from geoblock.adjust import adjust

    block = small.block()
    assert set(block.models) == set(small.layout.ids.tolist())
    result = adjust(block, max_iterations=10)
    assert result.converged
    # the adjusted models put the ICPs within a few metres of the truth; on board: ~30 m
    g = small.points.ground
    icp = np.flatnonzero(g.kind == "icp")
    before, after = [], []
    onboard = {i: s.onboard_model for i, s in small.sensors.items()}
    m = small.points.image
    index = {p: i for i, p in enumerate(g.id.tolist())}
    for which, models in ((before, onboard), (after, result.models)):
        for image in small.layout.ids.tolist():
            sel = (m.image == image) & (m.kind == "icp")
            if not sel.any():
                continue
            k = np.array([index[p] for p in m.id[sel].tolist()])
            got = models[image].backproject(m.row[sel], m.col[sel], g.h_true[k])
            _, _, d = GEOD.inv(got.lon, got.lat, g.lon_true[k], g.lat_true[k])
            which.append(d)
    rmse_before = float(np.sqrt(np.mean(np.concatenate(before) ** 2)))
    rmse_after = float(np.sqrt(np.mean(np.concatenate(after) ** 2)))
    assert icp.size == 30
    assert rmse_before > 15.0
    assert rmse_after < 0.5 * rmse_before


def test_continental_rendered_preset() -> None:
    sc = preset("continental-spot-100")
    assert len(sc.images) == 100
    spec = sc.images[0].spec
    assert spec.shape == (400, 400) and spec.gsd_m == pytest.approx(150.0)
    full = preset("continental-spot-100", "full")
    assert full.images[0].spec.shape == (3000, 3000)
    # the same layout as the large blocks
    lay = layout(LargeBlockSpec(name="continental-spot-100", strips=10, scenes=10, tps=0,
                                seed=100))
    assert [im.id for im in sc.images] == lay.ids.tolist()
    assert sc.images[57].spec.centre_lat == pytest.approx(lay.lat[57], abs=1e-6)


def test_cli_writes_a_large_preset(tmp_path) -> None:
    from click.testing import CliRunner

    from geoblock.cli.main import cli
    from geoblock.io import read_block, read_points

    out = tmp_path / "big"
    res = CliRunner().invoke(cli, ["simulate", "continental-spot-1000", str(out), "--images",
                                   "4", "--tps", "300", "--seed", "3"])
    assert res.exit_code == 0, res.output
    block = read_block(out / "block.toml")
    assert [im.id for im in block.images] == ["s000k000", "s000k001", "s001k000", "s001k001"]
    assert block.method == "dg" and block.dem is not None and block.dem.sigma == 10.0
    image = read_points(out / "points" / "image.csv")
    tp = np.asarray(image["kind"]) == "tp"
    assert np.unique(np.asarray(image["id"])[tp]).size == 300
    # the same block in memory
    lb = large_block(large_preset("continental-spot-1000", images=4, tps=300, seed=3))
    assert np.allclose(np.asarray(image["row"], float), lb.points.image.row)
    for args, word in ((["--variant", "full"], "--variant"), ([], None)):
        if word is None:
            continue
        res = CliRunner().invoke(cli, ["simulate", "continental-spot-1000",
                                       str(tmp_path / "x"), *args])
        assert res.exit_code != 0 and word in res.output
    res = CliRunner().invoke(cli, ["simulate", "teo2010-spot5", str(tmp_path / "y"), "--tps",
                                   "10"])
    assert res.exit_code != 0 and "large presets" in res.output
