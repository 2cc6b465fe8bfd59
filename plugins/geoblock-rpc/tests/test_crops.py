"""The RPC of a crop opens and projects as its scene's RPC shifted by the window (issue 26,
items 1 and 11).

s2p, rpcm and CARS write the RPC of a crop by keeping the scene's ground normalisation and
either shifting the image offsets by the window's origin, or re-normalising the image box to
the crop (``LINE_OFF``/``SAMP_OFF`` at the crop's centre, ``LINE_SCALE``/``SAMP_SCALE`` half
its size, numerators rescaled). Both must open (the plausibility rules of issue 12 refused 343
of 936 such crops of the shared RPCs) and project as the scene's RPC shifted by the window
(1e-9 px) and as GDAL's RPC transformer does (rasterio ``RPCTransformer``).
"""

from __future__ import annotations

import math
import warnings
from functools import cache

import numpy as np
import pytest
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import read_rpc
from geoblock_rpc.rpc00b import Rpc00b
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer

from geoblock.typing import Status

from .conftest import DATA_DIR, RPC_FILES

#: windows drawn (each gives one crop RPC per convention: >= 1000 crop RPCs in all)
WINDOWS = 500
#: agreement with the scene's RPC shifted by the window, pixels
SHIFT_TOL_PX = 1e-9
#: agreement with GDAL's RPC transformer (a direct evaluation in ground -> image), pixels
GDAL_TOL_PX = 1e-8


def crop_rpc(rpc: Rpc00b, row0: float, col0: float, rows: int, cols: int, *,
             renormalise: bool) -> Rpc00b:
    """The RPC of the window ``[row0, row0 + rows) x [col0, col0 + cols)`` of ``rpc``'s image.

    ``renormalise=False``: the offsets shifted by the window's origin (GDAL's, rpcm's
    ``crop``). ``True``: the image box re-normalised to the crop as s2p/CARS write it
    (``*_OFF`` the crop's centre, ``*_SCALE`` half its size, numerators rescaled so that the
    ratio gives the same pixel); the ground normalisation is the scene's in both.
    """
    if not renormalise:
        return rpc.replace(line_off=rpc.line_off - row0, samp_off=rpc.samp_off - col0)
    changes = {}
    for axis, origin, size in (("line", row0, rows), ("samp", col0, cols)):
        off, scale = getattr(rpc, f"{axis}_off"), getattr(rpc, f"{axis}_scale")
        new_off, new_scale = (size - 1) / 2.0, size / 2.0
        # row - origin = (N / D) scale + off - origin = (N' / D) new_scale + new_off
        changes[f"{axis}_num"] = (scale / new_scale * getattr(rpc, f"{axis}_num")
                                  + (off - origin - new_off) / new_scale
                                  * getattr(rpc, f"{axis}_den"))
        changes[f"{axis}_off"], changes[f"{axis}_scale"] = new_off, new_scale
    return rpc.replace(**changes)


@cache
def scene_rpcs() -> tuple[tuple[str, Rpc00b], ...]:
    """The distinct RPCs of the shared data, each with the first file that holds it."""
    out: dict[Rpc00b, str] = {}
    for rel in sorted(RPC_FILES):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rpc, _, _ = read_rpc(DATA_DIR / rel)
        out.setdefault(rpc, rel)
    return tuple((rel, rpc) for rpc, rel in out.items())


def _box(rpc: Rpc00b) -> tuple[int, int, int, int]:
    """The scene's image box as whole pixels: (first row, rows, first col, cols)."""
    r0 = math.ceil(rpc.line_off - abs(rpc.line_scale))
    c0 = math.ceil(rpc.samp_off - abs(rpc.samp_scale))
    return (r0, math.floor(rpc.line_off + abs(rpc.line_scale)) - r0 + 1,
            c0, math.floor(rpc.samp_off + abs(rpc.samp_scale)) - c0 + 1)


def _gdal_project(rpc: Rpc00b, lon, lat, h):
    """GDAL's ground -> (row, col), geoblock's convention (GDAL's pixel/line less 0.5)."""
    with RPCTransformer(RPC.from_gdal(rpc.to_gdal())) as tr:
        line, pixel = tr.rowcol(lon, lat, zs=h, op=np.positive)
    return np.asarray(line) - 0.5, np.asarray(pixel) - 0.5


def _check_window(rel, rpc, row0, col0, rows, cols, rng, errors):
    scene = RpcModel(rpc)
    # ground points seen by the window: its corners and random pixels at random heights
    u = np.concatenate([[0.0, 0.0, 1.0, 1.0, 0.5], rng.uniform(0, 1, 11)])
    v = np.concatenate([[0.0, 1.0, 0.0, 1.0, 0.5], rng.uniform(0, 1, 11)])
    row = row0 + u * (rows - 1)
    col = col0 + v * (cols - 1)
    h = rpc.height_off + rng.uniform(-1, 1, u.size) * abs(rpc.height_scale)
    ground, status = scene.backproject_with_status(row, col, h)
    # a zero of the denominator (ASP's sample.RPB) leaves a few pixels without a ground point
    ok = status == Status.CONVERGED
    assert np.mean(ok) >= 0.5, f"{rel}: the scene's RPC localises {status}"
    ground = type(ground)(ground.lon[ok], ground.lat[ok], ground.h[ok])
    (row, col), status = scene.project_with_status(ground.lon, ground.lat, ground.h)
    assert np.all(status == Status.CONVERGED)
    for renormalise in (False, True):
        crop = crop_rpc(rpc, row0, col0, rows, cols, renormalise=renormalise)
        model = RpcModel(crop, (rows, cols))  # refused before (issue 26 item 1)
        (r, c), status = model.project_with_status(ground.lon, ground.lat, ground.h)
        assert np.all(status == Status.CONVERGED), f"{rel} crop: status {status}"
        shift = float(np.max(np.hypot(r - (row - row0), c - (col - col0))))
        gr, gc = _gdal_project(crop, ground.lon, ground.lat, ground.h)
        gdal = float(np.max(np.hypot(r - gr, c - gc)))
        errors.append((shift, gdal, renormalise, rel, (row0, col0, rows, cols)))
        assert shift <= SHIFT_TOL_PX, (rel, renormalise, (row0, col0, rows, cols), shift)
        assert gdal <= GDAL_TOL_PX, (rel, renormalise, (row0, col0, rows, cols), gdal)


@pytest.fixture(scope="module")
def rpcs(data_dir):
    return scene_rpcs()


def test_random_crop_windows_of_every_shared_rpc_open_and_project_as_the_scene(rpcs):
    errors: list[tuple] = []

    @settings(max_examples=WINDOWS, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(data=st.data())
    def check(data: st.DataObject) -> None:
        rel, rpc = data.draw(st.sampled_from(rpcs), label="rpc")
        r0, n_rows, c0, n_cols = _box(rpc)
        rows = data.draw(st.integers(4, min(1024, n_rows)), label="rows")
        cols = data.draw(st.integers(4, min(1024, n_cols)), label="cols")
        row0 = data.draw(st.integers(r0, r0 + n_rows - rows), label="row0")
        col0 = data.draw(st.integers(c0, c0 + n_cols - cols), label="col0")
        seed = data.draw(st.integers(0, 2**32 - 1), label="seed")
        _check_window(rel, rpc, row0, col0, rows, cols, np.random.default_rng(seed), errors)

    check()
    assert len(errors) >= 2 * WINDOWS >= 1000
    worst = max(errors)
    print(f"\n{len(errors)} crop RPCs of {len(rpcs)} scene RPCs, 0 refused: max "
          f"{worst[0]:.2e} px from the shifted scene RPC ({worst[3]}), max "
          f"{max(e[1] for e in errors):.2e} px from GDAL")


@pytest.mark.parametrize("renormalise", [False, True])
@pytest.mark.parametrize("corner", ["first", "centre", "last"])
@pytest.mark.parametrize("size", [4, 1024])
def test_crops_at_the_corners_and_centre_of_every_shared_rpc_open(rpcs, renormalise, corner,
                                                                   size):
    """The grid of issue 26 item 1 (the s2p Pleiades crop: 1024 x 1024, LINE_SCALE 512, was
    refused with "the ground centre ... projects more than 10 scales from the image centre")."""
    rng = np.random.default_rng(0)
    for rel, rpc in rpcs:
        r0, n_rows, c0, n_cols = _box(rpc)
        rows, cols = min(size, n_rows), min(size, n_cols)
        k = {"first": 0.0, "centre": 0.5, "last": 1.0}[corner]
        row0 = r0 + round(k * (n_rows - rows))
        col0 = c0 + round(k * (n_cols - cols))
        crop = crop_rpc(rpc, row0, col0, rows, cols, renormalise=renormalise)
        RpcModel(crop, (rows, cols))
        _check_window(rel, rpc, row0, col0, rows, cols, rng, [])
