"""Control from a reference orthoimage on the real Pleiades pair of Mont Ventoux (issue 28):
the left crop's ortho through its vendor RPC and the SRTM (0.5 m, bicubic) is the reference
for the right crop. The right image adjusted by RPCV-0 on that control alone is compared with
the pair adjusted on tie points (geoblock match, left held fixed), and the block with both
with the tie points alone.

Measured (this machine, the files of ../shared/data): 502 control points of 523 candidates;
RPCV-0 on the reference control a0 = -3.508 +- 0.176, b0 = -4.034 +- 0.159 px; on the tie
points a0 = -3.005 +- 0.235, b0 = -4.134 +- 0.064 px: 0.50 px apart along rows, 0.10 along
columns. The two routes measure the same thing where they meet (the control points and the
tie points within 5 px of each other agree to 0.003 px); what differs is WHERE they measure:
the offsets between the RPCs vary by +-7 px along rows over the overlap (SRTM's errors under
buildings and trees, times the pair's parallax), the tie points sit on SIFT keypoints and the
control points on a regular grid, and RPCV-0 takes each set's mean. 0.5 px is about 2 sigma of
either route's posterior along rows: the 0.1 px the issue asks is below what either route
determines here, and the test says so (strict xfail) rather than loosening it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from geoblock.cli.main import build_cli
from geoblock.io import read_points, write_points

SRTM = "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"


@pytest.fixture(scope="module")
def runs(data_dir, tmp_path_factory):
    pytest.importorskip("geoblock_rpc", reason="the Ventoux RPCs need the geoblock-rpc plugin")
    f = {"srtm": data_dir / SRTM, "geoid": data_dir / GEOID}
    for side in ("left", "right"):
        f[f"{side}_image"] = data_dir / f"shareloc/image/phr_ventoux/{side}_image.tif"
        f[f"{side}_rpc"] = data_dir / f"shareloc/rpc/phr_ventoux/{side}_image.geom"
    for path in f.values():
        if not path.exists():
            pytest.skip(f"real data not found: {path}")
    tmp = tmp_path_factory.mktemp("ventoux-reference")
    cli, runner = build_cli(), CliRunner()

    def run(*args):
        result = runner.invoke(cli, [str(a) for a in args])
        assert result.exit_code == 0, result.output
        return result

    dem = ["--dem", f["srtm"], "--dem-vertical", "geoid", "--geoid", f["geoid"]]
    run("ortho", f["left_image"], tmp / "left_ortho.tif", "--model", f["left_rpc"], *dem,
        "--res", "0.5", "--resampling", "bicubic")
    ref = run("match", f["right_image"], "--model", f["right_rpc"], "--image-id", "right",
              *dem, "--dem-sigma", "10", "--reference", tmp / "left_ortho.tif",
              "--reference-accuracy", "8.5", "-o", tmp / "ref_image.csv", "--ground-output",
              tmp / "ref_ground.csv")
    head = f"""[dem]
path = "{f['srtm']}"
vertical = "geoid"
geoid = "{f['geoid']}"
sigma = 10.0
"""
    left = f'[[images]]\nid = "left"\nmodel = "{f["left_rpc"]}"\nraster = "{f["left_image"]}"\n'
    right = (f'[[images]]\nid = "right"\nmodel = "{f["right_rpc"]}"\n'
             f'raster = "{f["right_image"]}"\ncorrection = 0\n')
    top = 'version = 1\nmethod = "default"\n[points]\n'
    (tmp / "ref.toml").write_text(top + 'ground = "ref_ground.csv"\nimage = "ref_image.csv"\n'
                                  + head + right)
    (tmp / "tp.toml").write_text(top + 'image = "tp.csv"\n' + head + left + right)
    run("match", tmp / "tp.toml", "-o", tmp / "tp.csv", "--ictp-share", "0.1")
    a, b = read_points(tmp / "tp.csv"), read_points(tmp / "ref_image.csv")
    write_points(tmp / "both.csv", {k: np.concatenate([a[k], b[k]])
                                    for k in ("id", "image", "row", "col", "sigma", "kind")})
    (tmp / "both.toml").write_text('version = 1\nmethod = "default"\n[points]\nimage = "both.csv"\n'
                                   'ground = "ref_ground.csv"\n' + head + left + right)
    out = {"match": ref.stderr}
    for name in ("ref", "tp", "both"):
        run("adjust", tmp / f"{name}.toml", "-o", tmp / name, "--no-figures")
        out[name] = json.loads((tmp / name / "report.json").read_text())
    out["dir"] = tmp
    return out


def shift(report):
    return np.array([p["value"] for p in report["parameters"]["right"]])


def test_reference_control_on_the_left_ortho(runs):
    assert "reference control points in 1 of 1 image(s) from left_ortho.tif" in runs["match"]
    g = read_points(runs["dir"] / "ref_ground.csv")
    assert g["id"].size >= 300
    assert set(g["source"]) == {"reference:left_ortho.tif"}
    ref, tp = shift(runs["ref"]), shift(runs["tp"])
    # both see the RPCs' disagreement of about 3 and 4 px
    assert np.all(np.abs(ref - tp) < 1.0), (ref, tp)
    sig = np.hypot([p["sigma"] for p in runs["ref"]["parameters"]["right"]],
                   [p["sigma"] for p in runs["tp"]["parameters"]["right"]])
    assert np.all(np.abs(ref - tp) < 3 * sig), (ref, tp, sig)


def test_reference_and_tie_points_measure_the_same_where_they_meet(runs):
    from scipy.spatial import cKDTree

    import geoblock

    d = runs["dir"]
    g, m = read_points(d / "ref_ground.csv"), read_points(d / "ref_image.csv")
    t = read_points(d / "tp.csv")
    spec = geoblock.io.read_block(d / "tp.toml")
    left = geoblock.open_model(spec.image("left").model)
    right = geoblock.open_model(spec.image("right").model)
    dem = spec.dem.to_source()
    pr = right.project(g["lon"], g["lat"], g["h"])
    pl = left.project(g["lon"], g["lat"], g["h"])
    il, r = t["image"] == "left", t["image"] == "right"
    assert np.array_equal(t["id"][il], t["id"][r])
    gl, status = geoblock.localize(left, t["row"][il], t["col"][il], dem, warn=False)
    p = right.project(gl.lon, gl.lat, gl.h)
    off_ref = np.c_[m["row"] - pr.row, m["col"] - pr.col]
    off_tp = np.c_[t["row"][r] - p.row, t["col"][r] - p.col]
    dist, near = cKDTree(np.c_[t["row"][il], t["col"][il]]).query(np.c_[pl.row, pl.col])
    close = dist < 5
    assert close.sum() >= 50
    # measured: 0.003 px
    assert np.all(np.abs(np.median(off_ref[close] - off_tp[near[close]], axis=0)) < 0.05)


def test_the_block_ictps_are_no_worse_with_reference_control(runs):
    tp_rmse = _ictp_rmse(runs["tp"])
    both_rmse = _ictp_rmse(runs["both"])
    # measured: 2.808 m (tie points alone) and 2.823 m (with the reference control)
    assert both_rmse <= 1.01 * tp_rmse, (both_rmse, tp_rmse)


def _ictp_rmse(report):
    return float(report["statistics"]["ictp"]["left & right"]["rmse_2d"])


@pytest.mark.xfail(strict=True, reason="the issue's 0.1 px: the routes sample the RPCs' "
                   "+-7 px varying offset field at different places (module docstring); "
                   "measured 0.50 px along rows, within 2 sigma of either route")
def test_rpcv0_shifts_within_a_tenth_of_a_pixel(runs):
    assert np.all(np.abs(shift(runs["ref"]) - shift(runs["tp"])) < 0.1)
