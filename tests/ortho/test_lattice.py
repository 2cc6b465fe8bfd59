"""The (E, N, h) lattice: error against the exact model, chunk independence, every model."""

from __future__ import annotations

import numpy as np
import pytest
from affine import Affine

from geoblock.dem import ConstantDem, GridDem
from geoblock.models import ImageCorrection
from geoblock.ortho.grid import OutputGrid
from geoblock.ortho.lattice import LatticeInfo, source_coordinates
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom


def _rpc():
    from geoblock_rpc import RpcModel

    return RpcModel.example()


def _terrain(lon0: float, lat0: float) -> GridDem:
    """Rough terrain: 200-1400 m on 0.004 degree posts around (lon0, lat0)."""
    rng = np.random.default_rng(7)
    heights = rng.uniform(200.0, 1400.0, (40, 40))
    return GridDem(heights, Affine(0.004, 0.0, lon0 - 0.08, 0.0, -0.004, lat0 + 0.08),
                   "EPSG:4326")


def _exact(model, dem, grid, rows, cols):
    lon, lat = grid.lonlat(rows, cols)
    h = dem.height(lon, lat)
    (r, c), _ = model.project_with_status(lon, lat, h)
    return r, c


CASES = {
    "rpc": (_rpc, (4000, 5000), 512),
    "pushbroom": (lambda: ConstantVelocityPushbroom.example((600, 700)), (0, 0), 512),
    "affine-corrected": (
        lambda: ImageCorrection(AffineCamera.example((500, 600)), order=1,
                                values=[0.3, 1e-4, -2e-4, -0.2, 2e-4, 1e-4]),
        (0, 0), 400),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("tolerance", [0.01, 0.002])
def test_lattice_error_below_tolerance(case, tolerance):
    make, (r0, c0), size = CASES[case]
    model = make()
    dem = _terrain(7.05, 43.70)
    grid = OutputGrid.for_model(model, dem)
    window = (slice(r0, r0 + size), slice(c0, c0 + size))
    info = LatticeInfo()
    row, col, valid = source_coordinates(model, dem, grid, tolerance_px=tolerance,
                                         window=window, info=info)
    assert row.shape == col.shape == valid.shape == (size, size)
    assert valid.mean() > 0.9
    rng = np.random.default_rng(123)
    ii = rng.integers(0, size, 3000)
    jj = rng.integers(0, size, 3000)
    er, ec = _exact(model, dem, grid, ii + r0, jj + c0)
    err = np.hypot(row[ii, jj] - er, col[ii, jj] - ec)
    assert np.isfinite(er).sum() > 2500
    np.testing.assert_array_equal(np.isfinite(err), np.isfinite(er))
    assert np.nanmax(err) <= tolerance
    assert max(info.check_error_px.values()) <= tolerance
    assert info.spacing  # a lattice was used, not only exact projection
    assert all(s > 0 for s, _ in info.spacing.values())


def test_exact_mode_is_exact():
    model = ConstantVelocityPushbroom.example((300, 300))
    dem = _terrain(7.05, 43.70)
    grid = OutputGrid.for_model(model, dem)[:100, :120]
    row, col, valid = source_coordinates(model, dem, grid, tolerance_px=0)
    rr, cc = np.meshgrid(np.arange(100), np.arange(120), indexing="ij")
    er, ec = _exact(model, dem, grid, rr, cc)
    np.testing.assert_array_equal(row, er)
    np.testing.assert_array_equal(col, ec)
    np.testing.assert_array_equal(valid, np.isfinite(er))


@pytest.mark.parametrize("tolerance", [0.01, 0.0])
def test_chunk_independent(tolerance):
    model = ConstantVelocityPushbroom.example((300, 340))
    dem = _terrain(7.05, 43.70)
    grid = OutputGrid.for_model(model, dem)
    whole = source_coordinates(model, dem, grid, tolerance_px=tolerance, block_px=64)
    for size in (37, 100):
        parts = [np.full(grid.shape, np.nan), np.full(grid.shape, np.nan)]
        for rs, cs in grid.chunks(size):
            r, c, _ = source_coordinates(model, dem, grid, tolerance_px=tolerance,
                                         window=(rs, cs), block_px=64)
            parts[0][rs, cs] = r
            parts[1][rs, cs] = c
        assert parts[0].tobytes() == whole[0].tobytes()
        assert parts[1].tobytes() == whole[1].tobytes()


def test_no_dem_is_invalid():
    model = AffineCamera.example((200, 200))
    far = GridDem(np.full((4, 4), 100.0), Affine(0.01, 0, 20.0, 0, -0.01, 10.0), "EPSG:4326")
    grid = OutputGrid.for_model(model, ConstantDem(100.0))[:64, :64]
    row, col, valid = source_coordinates(model, far, grid)
    assert not valid.any() and np.isnan(row).all() and np.isnan(col).all()


def test_bad_arguments():
    model = AffineCamera.example((50, 50))
    grid = OutputGrid.for_model(model, ConstantDem(0.0))
    with pytest.raises(ValueError, match="power of two"):
        source_coordinates(model, ConstantDem(0.0), grid, block_px=100)
    with pytest.raises(ValueError, match="tolerance"):
        source_coordinates(model, ConstantDem(0.0), grid, tolerance_px=-1)
