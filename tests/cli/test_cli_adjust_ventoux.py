"""A block of two real Pleiades RPCs (shareloc's Ventoux pair) on the real SRTM tile.

``right_image_bias.geom`` is ``right_image.geom`` with LINE_OFF moved by 60 rows (shareloc's
refinement test data). Tie points are made with the unbiased RPCs on the SRTM terrain (EGM96
heights converted through the real geoid grid), measured with 0.3 px noise; the block holds
the left image fixed and refines the biased right one with RPCV-0, with the SRTM as elevation
control and no GCP at all: the 60-row bias must come out, through the block file and the
command line as a user would run it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import geoblock
from geoblock.io import write_points

VENTOUX = "shareloc/rpc/phr_ventoux"


@pytest.fixture(scope="module")
def ventoux(data_dir, tmp_path_factory):
    pytest.importorskip("geoblock_rpc")
    files = {name: data_dir / VENTOUX / f"{name}.geom"
             for name in ("left_image", "right_image", "right_image_bias")}
    srtm = data_dir / "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
    geoid = data_dir / "shareloc/dtm/geoid/egm96_15.gtx"
    for path in (*files.values(), srtm, geoid):
        if not path.exists():
            pytest.skip(f"{path} not found")
    left = geoblock.open_model(files["left_image"])
    right = geoblock.open_model(files["right_image"])
    dem = geoblock.open_dem(srtm, vertical="geoid", geoid=geoid)
    rng = np.random.default_rng(7)
    # ground points over the left image's footprint, on the SRTM surface
    rows = rng.uniform(500, left.shape[0] - 500, 400)
    cols = rng.uniform(500, left.shape[1] - 500, 400)
    g, status = geoblock.localize(left, rows, cols, dem)
    r2, c2 = right.project(g.lon, g.lat, g.h)
    inside = (status == 0) & (r2 > 0) & (r2 < right.shape[0]) & (c2 > 0) & (c2 < right.shape[1])
    n = int(inside.sum())
    ids = np.array([f"tp{k:03d}" for k in range(n)])
    sigma = 0.3
    meas = {
        "id": np.concatenate([ids, ids]),
        "image": np.array(["left"] * n + ["right"] * n),
        "row": np.concatenate([rows[inside], r2[inside]]) + sigma * rng.normal(size=2 * n),
        "col": np.concatenate([cols[inside], c2[inside]]) + sigma * rng.normal(size=2 * n),
        "sigma": np.full(2 * n, sigma),
        "kind": np.array(["tp"] * (2 * n), dtype="<U4"),
    }
    # every fifth point is kept as an ICTP
    meas["kind"][np.isin(meas["id"], ids[::5])] = "ictp"
    out = tmp_path_factory.mktemp("ventoux")
    write_points(out / "image.csv", meas)
    (out / "block.toml").write_text(f"""
version = 1
name = "Ventoux Pleiades pair, right RPC biased by 60 rows"
method = "default"

[points]
image = "image.csv"

[dem]
path = "{srtm}"
vertical = "geoid"
geoid = "{geoid}"
sigma = 10.0

[[images]]
id = "left"
model = "{files['left_image']}"

[[images]]
id = "right"
model = "{files['right_image_bias']}"
correction = 0
""")
    return {"dir": out, "right": right, "dem": dem}


def test_the_block_removes_the_60_row_bias(ventoux, runner, cli):
    out = ventoux["dir"] / "adjusted"
    result = runner.invoke(cli, ["adjust", str(ventoux["dir"] / "block.toml"), "-o", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads((out / "report.json").read_text())
    a0, b0 = (p["value"] for p in report["parameters"]["right"])
    sig = [p["sigma"] for p in report["parameters"]["right"]]
    # along-track (row) the shift trades with the TP heights: the SRTM (10 m) decides it
    assert sig[0] < 0.5 and sig[1] < 0.1, sig
    assert abs(a0 + 60.0) < 3 * sig[0] and abs(b0) < 3 * sig[1], (a0, b0, sig)
    # the TPs lie exactly on the SRTM: the DEM rows (sigma 10 m) have no residual, so sigma0
    # is below 1 (about sqrt(1/2): half of each TP's redundancy carries no error)
    assert 0.5 < report["sigma0"] < 1.1
    # the adjusted right model reproduces the unbiased RPC
    adjusted = geoblock.open_model(out / "models" / "right.json")
    lon = np.linspace(5.2, 5.35, 5)
    lat = np.linspace(44.1, 44.2, 5)
    h = ventoux["dem"].height(lon, lat)
    r0, c0 = ventoux["right"].project(lon, lat, h)
    r1, c1 = adjusted.project(lon, lat, h)
    assert np.max(np.hypot(r1 - r0, c1 - c0)) < 0.3
    # and the two images agree again at the ICTPs
    ictp = report["statistics"]["ictp"]["left & right"]
    assert ictp["rmse_2d"] < 1.5  # metres: 0.3 px noise at 0.5 m GSD through the SRTM
