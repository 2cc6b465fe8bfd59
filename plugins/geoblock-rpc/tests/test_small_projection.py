"""The numpy projection of small batches (geoblock_rpc._small): the compiled kernels' bits.

Which path projects a batch depends on its size and on whether the process has imported numba
(geoblock_rpc.model._use_numpy); results must not (the orthorectifier's byte-identical output
across dask schedulers rests on it), so row, col and status are compared as bytes, NaNs
included, against the serial and the parallel kernel.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from geoblock_rpc import RpcModel, _kernels, _small
from geoblock_rpc import model as model_module
from hypothesis import given, settings
from hypothesis import strategies as st

import geoblock
from geoblock import Status

PLEIADES = "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"


def _run_all(model: RpcModel, lon, lat, h) -> list[bytes]:
    """Each path's (row, col, status) as one byte string: numpy, serial kernel, parallel."""
    out = []
    for project in (_small.project, _kernels.project_serial, _kernels.project):
        n = lon.shape[0]
        row, col, status = np.full(n, 7.0), np.full(n, 7.0), np.full(n, 9, np.uint8)
        project(lon, lat, h, model._prm, model._coef, row, col, status)
        out.append(row.tobytes() + col.tobytes() + status.tobytes())
    return out


def _ground_points(model: RpcModel, n: int, seed: int):
    """Points over and around the image (inside and outside the domain), heights beyond the
    valid range, and every kind of bad input."""
    rng = np.random.default_rng(seed)
    rows, cols = model.shape
    lo, hi = model.valid_height_range
    h = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), n)
    g, _ = model.backproject_with_status(rng.uniform(-0.3 * rows, 1.3 * rows, n),
                                         rng.uniform(-0.3 * cols, 1.3 * cols, n), h)
    rpc = model.rpc
    lon = np.where(np.isfinite(g.lon), g.lon,
                   rpc.long_off + rng.normal(0.0, 2.0 * abs(rpc.long_scale), n))
    lat = np.where(np.isfinite(g.lat), g.lat,
                   rpc.lat_off + rng.normal(0.0, 2.0 * abs(rpc.lat_scale), n))
    lon[:6] = [np.nan, np.inf, -np.inf, 1e300, lon[6] + 360.0, lon[7] - 720.0]
    lat[6:9] = [np.nan, 91.0, -np.inf]
    h[9:12] = [np.nan, 1e7, -1e300]
    return lon, lat, h


def test_small_batches_give_the_kernels_bits_on_every_rpc_file(rpc_file, data_dir):
    model = geoblock.open_model(data_dir / rpc_file, model="rpc")
    lon, lat, h = _ground_points(model, 3001, seed=len(rpc_file))
    small, serial, parallel = _run_all(model, lon, lat, h)
    assert small == serial
    assert small == parallel
    _, status = model.project_with_status(lon, lat, h)
    # the sample reaches the statuses it is meant to test, in the kernel's precedence
    assert {Status.CONVERGED, Status.OUT_OF_DOMAIN, Status.INVALID_INPUT} <= set(status.tolist())
    assert list(status[:3]) == [Status.INVALID_INPUT] * 3
    assert status[3] == Status.OUT_OF_DOMAIN  # 1e300: no place on the Earth


def test_a_zero_denominator_somewhere_is_diverged_with_the_same_bits():
    model = RpcModel.example()
    lon, lat, h = _ground_points(model, 500, seed=5)
    coef = model._coef.copy()
    coef[3, 0] = 0.0  # samp_den: zero at L = P = H = 0, the model's centre
    coef[3, 1:] = 0.0
    coef[3, 3] = 1.0  # samp_den = H: zero at HEIGHT_OFF
    h[100:110] = model.rpc.height_off
    outs = []
    for project in (_small.project, _kernels.project_serial, _kernels.project):
        row, col, status = np.empty(500), np.empty(500), np.empty(500, np.uint8)
        project(lon, lat, h, model._prm, coef, row, col, status)
        outs.append(row.tobytes() + col.tobytes() + status.tobytes())
    assert outs[0] == outs[1] == outs[2]
    assert Status.DIVERGED in status[100:110]


_SPECIAL = st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e300, 0.0, -0.0, 5e-324])


@pytest.fixture(scope="module")
def models(data_dir):
    return [RpcModel.example()] + [
        geoblock.open_model(data_dir / rel, model="rpc")
        for rel in (PLEIADES, "gdal-autotest/extracted/transformer_15_rpc.vrt",
                    "stereopipeline/tests/sample.RPB")]


@settings(max_examples=150, deadline=None)
@given(which=st.integers(0, 3),
       points=st.lists(st.tuples(st.floats(-3.0, 3.0) | _SPECIAL, st.floats(-3.0, 3.0) | _SPECIAL,
                                 st.floats(-8.0, 8.0) | _SPECIAL),
                       min_size=1, max_size=40))
def test_hypothesis_points_inside_and_outside_the_domain(models, which, points):
    """Normalised ground points from the middle of the domain to far outside it (the domain
    is |L|, |P| <= 1.5 and the height limit), with NaN, inf, huge values and signed zeros."""
    model = models[which]
    rpc = model.rpc
    L, P, H = (np.array(v, dtype=np.float64) for v in zip(*points, strict=True))
    with np.errstate(all="ignore"):
        lon = rpc.long_off + L * rpc.long_scale
        lat = rpc.lat_off + P * rpc.lat_scale
        h = rpc.height_off + H * rpc.height_scale
    small, serial, parallel = _run_all(model, lon, lat, h)
    assert small == serial == parallel


@pytest.mark.parametrize("path", ["numpy", "kernel"])
def test_results_do_not_depend_on_the_batch_size_or_the_path(monkeypatch, path):
    """The model's public call, batch by batch in uneven pieces on either path, gives the bits
    of one call on the other."""
    model = RpcModel.example()
    lon, lat, h = _ground_points(model, 5000, seed=11)
    monkeypatch.setattr(model_module, "_use_numpy", lambda n: path == "kernel")
    (row, col), status = model.project_with_status(lon, lat, h)
    whole = row.tobytes() + col.tobytes() + status.tobytes()
    monkeypatch.setattr(model_module, "_use_numpy", lambda n: path == "numpy")
    cuts = [0, 1, 2, 17, 1000, 1001, 4097, 5000]
    parts = [model.project_with_status(lon[a:b], lat[a:b], h[a:b])
             for a, b in zip(cuts, cuts[1:], strict=False)]
    pieces = (np.concatenate([p[0][0] for p in parts]).tobytes()
              + np.concatenate([p[0][1] for p in parts]).tobytes()
              + np.concatenate([p[1] for p in parts]).tobytes())
    assert pieces == whole


def test_the_path_rule(monkeypatch):
    """numpy for batches up to SMALL_BATCH_MAX while numba is not imported, within the
    process's budget; the kernel otherwise."""
    use = model_module._use_numpy
    monkeypatch.setattr(model_module, "_small_points", 0)
    monkeypatch.delitem(sys.modules, "numba")
    assert use(10)
    assert not use(model_module.SMALL_BATCH_MAX + 1)
    monkeypatch.setattr(model_module, "_small_points",
                        model_module.SMALL_BUDGET_POINTS - 10)
    assert use(10)
    assert not use(1)  # the budget is spent: load the kernels
    monkeypatch.setattr(model_module, "_small_points", 0)
    monkeypatch.setitem(sys.modules, "numba", object())
    assert not use(10)


def test_a_command_that_projects_a_few_points_imports_no_numba(data_dir, tmp_path):
    """Opening the Pleiades RPC, projecting 10 points through the CLI and the API, localising
    them back, and ``geoblock plugins`` leave numba unimported; the bits are the kernel's."""
    model = geoblock.open_model(data_dir / PLEIADES, model="rpc")
    from geoblock_rpc.reference import localise

    lon, lat, _ = localise(model.rpc, np.linspace(10.0, model.shape[0] - 10.0, 10),
                           np.linspace(10.0, model.shape[1] - 10.0, 10), np.full(10, 100.0))
    points = tmp_path / "p10.csv"
    points.write_text("id,lon,lat,h\n" + "".join(
        f"p{i},{float(lon[i])!r},{float(lat[i])!r},100.0\n" for i in range(10)))
    row, col, status = np.empty(10), np.empty(10), np.empty(10, np.uint8)
    _kernels.project_serial(lon, lat, np.full(10, 100.0), model._prm, model._coef, row, col,
                            status)
    code = textwrap.dedent(f"""
        import contextlib, io, json, sys
        import numpy as np
        import geoblock
        from geoblock.cli.main import main
        with contextlib.redirect_stdout(io.StringIO()):
            for args in (["plugins"], ["project", {str(data_dir / PLEIADES)!r}, {str(points)!r}]):
                try:
                    main(args)
                except SystemExit:
                    pass
        model = geoblock.open_model({str(data_dir / PLEIADES)!r}, model="rpc")
        table = geoblock.read_points({str(points)!r})
        (row, col), status = model.project_with_status(table["lon"], table["lat"], table["h"])
        g, _ = model.backproject_with_status(row, col, table["h"])
        print(json.dumps(["numba" in sys.modules, row.tobytes().hex(), col.tobytes().hex(),
                          status.tolist(), g.lon.tobytes().hex()]))
    """)
    env = {k: v for k, v in os.environ.items() if k != "GEOBLOCK_PLUGIN_MODULES"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, env=env)
    numba_imported, row_hex, col_hex, statuses, lon_hex = json.loads(
        proc.stdout.strip().splitlines()[-1])
    assert numba_imported is False
    assert statuses == [Status.CONVERGED] * 10 == status.tolist()
    assert bytes.fromhex(row_hex) == row.tobytes() and bytes.fromhex(col_hex) == col.tobytes()
    g, _ = model.backproject_with_status(row, col, np.full(10, 100.0))  # the kernel, here
    assert bytes.fromhex(lon_hex) == g.lon.tobytes()


# ---------------------------------------------------------------------- localisation
def _run_localise(model: RpcModel, row, col, h, coef=None) -> list[bytes]:
    """Each path's (lon, lat, status) as one byte string: numpy, serial kernel, parallel."""
    coef = model._coef if coef is None else coef
    out = []
    for localise in (_small.localise, _kernels.localise_serial, _kernels.localise):
        n = row.shape[0]
        lon, lat, status = np.full(n, 7.0), np.full(n, 7.0), np.full(n, 9, np.uint8)
        localise(row, col, h, model._prm, coef, model.localisation_tolerance_px,
                 model.localisation_stall_px, model.localisation_max_iterations, lon, lat, status)
        out.append(lon.tobytes() + lat.tobytes() + status.tobytes())
    return out


def _image_points(model: RpcModel, n: int, seed: int):
    rng = np.random.default_rng(seed)
    rows, cols = model.shape
    lo, hi = model.valid_height_range
    row = rng.uniform(-0.3 * rows, 1.3 * rows, n)
    col = rng.uniform(-0.3 * cols, 1.3 * cols, n)
    h = rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), n)
    row[:3] = [np.nan, np.inf, 1e300]
    col[3] = -np.inf
    h[4:6] = [np.nan, 1e7]
    return row, col, h


def test_small_localisation_gives_the_kernels_bits_on_every_rpc_file(rpc_file, data_dir):
    model = geoblock.open_model(data_dir / rpc_file, model="rpc")
    row, col, h = _image_points(model, 1501, seed=len(rpc_file))
    small, serial, parallel = _run_localise(model, row, col, h)
    assert small == serial
    assert small == parallel
    _, status = model.backproject_with_status(row, col, h)
    assert {Status.CONVERGED, Status.OUT_OF_DOMAIN, Status.INVALID_INPUT} <= set(status.tolist())


def test_small_localisation_of_a_degenerate_rpc_gives_the_kernels_bits():
    """Zero and vanishing denominators and Jacobians: DIVERGED and MAX_ITERATIONS points."""
    model = RpcModel.example()
    row, col, h = _image_points(model, 800, seed=4)
    for change in ((3, slice(None), 0.0), (1, slice(1, None), 0.0), (0, slice(1, 3), 0.0)):
        coef = model._coef.copy()
        coef[change[0], change[1]] = change[2]
        small, serial, parallel = _run_localise(model, row, col, h, coef)
        assert small == serial == parallel


@settings(max_examples=100, deadline=None)
@given(which=st.integers(0, 3),
       points=st.lists(st.tuples(st.floats(-2.0, 2.0) | _SPECIAL, st.floats(-2.0, 2.0) | _SPECIAL,
                                 st.floats(-8.0, 8.0) | _SPECIAL),
                       min_size=1, max_size=30))
def test_hypothesis_image_points_inside_and_outside_the_image(models, which, points):
    model = models[which]
    rpc = model.rpc
    ln, sn, H = (np.array(v, dtype=np.float64) for v in zip(*points, strict=True))
    with np.errstate(all="ignore"):
        row = rpc.line_off + ln * rpc.line_scale
        col = rpc.samp_off + sn * rpc.samp_scale
        h = rpc.height_off + H * rpc.height_scale
    small, serial, parallel = _run_localise(model, row, col, h)
    assert small == serial == parallel


@pytest.mark.parametrize("path", ["numpy", "kernel"])
def test_localisation_does_not_depend_on_the_batch_size_or_the_path(monkeypatch, path):
    model = RpcModel.example()
    row, col, h = _image_points(model, 3000, seed=12)
    monkeypatch.setattr(model_module, "_use_numpy", lambda n: path == "kernel")
    g, status = model.backproject_with_status(row, col, h)
    whole = g.lon.tobytes() + g.lat.tobytes() + g.h.tobytes() + status.tobytes()
    monkeypatch.setattr(model_module, "_use_numpy", lambda n: path == "numpy")
    cuts = [0, 1, 2, 17, 1000, 1001, 3000]
    parts = [model.backproject_with_status(row[a:b], col[a:b], h[a:b])
             for a, b in zip(cuts, cuts[1:], strict=False)]
    pieces = b"".join(np.concatenate([p[0][k] for p in parts]).tobytes() for k in range(3))
    assert pieces + np.concatenate([p[1] for p in parts]).tobytes() == whole
