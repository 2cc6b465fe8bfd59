"""Control from a reference orthoimage on the real Pleiades pair of Mont Ventoux (issue 28):
the left crop's ortho through its vendor RPC and the SRTM (0.5 m, bicubic) is the reference
for the right crop. The right image adjusted by RPCV-0 on that control alone (the reference
held fixed: its common shift's sigma set to 0, as the tie-point route holds the left image
fixed) is compared with the pair adjusted on tie points (geoblock match, left held fixed,
the TP heights on the SRTM with 10 m), and the block with both with the tie points alone.

What the two routes measure (measured on this machine with the files of ../shared/data; the
table is in docs/user-guide/without-gcps.md, "The Ventoux walk-through"). RPCV-0 on each
route is the mean, over its points, of the offset between where the right image sees a
feature and where its RPC puts the left's view of it on the SRTM. A DEM error dh moves that
offset along the pair's **parallax direction** (0.69 right pixels per metre, mostly along
rows): the offsets vary by 5.4 px (1 sigma) along it over the overlap, from +4 to -11 px
across the columns (SRTM's 90 m posts under the village and the trees). All points: control
a0 = -3.468 +- 0.264, b0 = -4.044 +- 0.055 px; tie points a0 = -3.005 +- 0.235,
b0 = -4.134 +- 0.064 px (0.463 / 0.090 apart). So:

* **across the parallax** (what the two views measure whatever the heights) the routes agree:
  -4.815 against -4.780 px, 0.035 px apart;
* **along it** each route's shift is the DEM's mean error over its own points times the
  parallax: 502 control points on a grid and 708 tie points on SIFT keypoints, 72 of which
  lie in a band along the overlap's edge where no 21 px patch fits (their offsets average
  -0.2 px along rows against -3.3 px for the others): 0.470 px apart, 0.7 m of mean SRTM
  height, 1.4 of the two routes' combined posterior sigma;
* on the **same features** (the 153 control points with a tie point within 3 px in the left
  image, and those 153 tie points) the shifts agree to 0.033 px along rows, 0.011 along
  columns; on a DEM made from the pair itself (the tie points, interpolated; the ortho and
  both routes on it) to 0.001 / 0.033 px (investigation, not run here: it needs the DEM
  written and a second ortho). Robust estimation (huber, cauchy) moves neither route by more
  than 0.003 px.

The issue's 0.1 px is therefore asserted where it is physically meaningful (same features;
the component across the parallax), and the raw routes' difference is asserted to be what
the two samples of the SRTM's error predict, rather than hidden behind a looser bound.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from geoblock.cli.main import build_cli
from geoblock.io import read_points, write_points

SRTM = "shareloc/dtm/srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"
#: Image rows and the shift's two components, pixels: the issue's bound.
TENTH_PX = 0.1
#: The control points and tie points on the same feature: within this many left pixels.
SAME_FEATURE_PX = 3.0


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
    # the reference held fixed, as the tie points hold the left image: with its common shift
    # free, the right image's shift and the reference's are one unknown on this control alone
    g = read_points(tmp / "ref_ground.csv")
    write_points(tmp / "ref_ground_fixed.csv",
                 {k: (np.zeros_like(v) if k.startswith("sigma_shift_") else v)
                  for k, v in g.items()})
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

    def block(name, image, ground=None, with_left=True):
        text = top + f'image = "{image}"\n' + (f'ground = "{ground}"\n' if ground else "")
        (tmp / f"{name}.toml").write_text(text + head + (left if with_left else "") + right)

    block("ref", "ref_image.csv", "ref_ground_fixed.csv", with_left=False)
    block("tp", "tp.csv")
    run("match", tmp / "tp.toml", "-o", tmp / "tp.csv", "--ictp-share", "0.1")
    a, b = read_points(tmp / "tp.csv"), read_points(tmp / "ref_image.csv")
    write_points(tmp / "both.csv", {k: np.concatenate([a[k], b[k]])
                                    for k in ("id", "image", "row", "col", "sigma", "kind")})
    block("both", "both.csv", "ref_ground.csv")
    offsets = _offsets(tmp)
    # the same features: control points with a tie point within SAME_FEATURE_PX, those TPs
    same = offsets["distance"] < SAME_FEATURE_PX
    ref_ids = offsets["ref_id"][same]
    tp_ids = np.unique(offsets["tp_id"][offsets["nearest"][same]])
    m = read_points(tmp / "ref_image.csv")
    gf = read_points(tmp / "ref_ground_fixed.csv")
    write_points(tmp / "same_ref_image.csv", {k: v[np.isin(m["id"], ref_ids)]
                                              for k, v in m.items()})
    write_points(tmp / "same_ref_ground.csv", {k: v[np.isin(gf["id"], ref_ids)]
                                               for k, v in gf.items()})
    write_points(tmp / "same_tp.csv", {k: v[np.isin(a["id"], tp_ids) | (a["kind"] == "ictp")]
                                       for k, v in a.items()})
    block("same_ref", "same_ref_image.csv", "same_ref_ground.csv", with_left=False)
    block("same_tp", "same_tp.csv")
    out = {"match": ref.stderr, "offsets": offsets, "same": (int(same.sum()), tp_ids.size)}
    for name in ("ref", "tp", "both", "same_ref", "same_tp"):
        run("adjust", tmp / f"{name}.toml", "-o", tmp / name, "--no-figures")
        out[name] = json.loads((tmp / name / "report.json").read_text())
    out["dir"] = tmp
    return out


def _offsets(d):
    """Per point, where the right image sees it minus where its RPC puts it (pixels): the
    control points' grounds, the tie points' left positions located on the SRTM; the left
    positions; each control point's nearest tie point; the parallax direction."""
    from scipy.spatial import cKDTree

    import geoblock

    g, m = read_points(d / "ref_ground.csv"), read_points(d / "ref_image.csv")
    t = read_points(d / "tp.csv")
    spec = geoblock.io.read_block(d / "tp.toml")
    left = geoblock.open_model(spec.image("left").model)
    right = geoblock.open_model(spec.image("right").model)
    dem = spec.dem.to_source()
    pr = right.project(g["lon"], g["lat"], g["h"])
    pl = left.project(g["lon"], g["lat"], g["h"])
    il, ir = t["image"] == "left", t["image"] == "right"
    assert np.array_equal(t["id"][il], t["id"][ir])
    tp = t["kind"][il] == "tp"
    gl, _ = geoblock.localize(left, t["row"][il], t["col"][il], dem, warn=False)
    p = right.project(gl.lon, gl.lat, gl.h)
    # the parallax: the right image's motion per metre up the left's line of sight
    up = left.backproject(t["row"][il], t["col"][il], gl.h + 10.0)
    q = right.project(up.lon, up.lat, up.h)
    e = np.array([np.median(q.row - p.row), np.median(q.col - p.col)]) / 10.0
    tp_left = np.c_[t["row"][il], t["col"][il]][tp]
    distance, nearest = cKDTree(tp_left).query(np.c_[pl.row, pl.col])
    return {"ref": np.c_[m["row"] - pr.row, m["col"] - pr.col],
            "tp": np.c_[t["row"][ir] - p.row, t["col"][ir] - p.col][tp],
            "ref_id": m["id"], "tp_id": t["id"][il][tp], "distance": distance,
            "nearest": nearest, "parallax": e}


def shift(report):
    return np.array([p["value"] for p in report["parameters"]["right"]])


def sigma(report):
    return np.array([p["sigma"] for p in report["parameters"]["right"]])


def along_across(runs, v):
    """``v`` (row, col) along and across the pair's parallax direction, pixels."""
    e = runs["offsets"]["parallax"]
    u = e / np.hypot(*e)
    return float(v @ u), float(v @ np.array([u[1], -u[0]]))


def test_reference_control_on_the_left_ortho(runs):
    assert "reference control points in 1 of 1 image(s) from left_ortho.tif" in runs["match"]
    g = read_points(runs["dir"] / "ref_ground.csv")
    assert g["id"].size >= 300
    assert set(g["source"]) == {"reference:left_ortho.tif"}
    ref, tp = shift(runs["ref"]), shift(runs["tp"])
    # both see the RPCs' disagreement of about 3 and 4 px
    assert np.all(np.abs(ref - tp) < 1.0), (ref, tp)
    sig = np.hypot(sigma(runs["ref"]), sigma(runs["tp"]))
    assert np.all(np.abs(ref - tp) < 3 * sig), (ref, tp, sig)


def test_reference_and_tie_points_measure_the_same_where_they_meet(runs):
    o = runs["offsets"]
    close = o["distance"] < 5
    assert close.sum() >= 50
    # measured: 0.002 / 0.009 px (303 pairs)
    diff = o["ref"][close] - o["tp"][o["nearest"][close]]
    assert np.all(np.abs(np.median(diff, axis=0)) < 0.05)


def test_rpcv0_shifts_on_the_same_features_within_a_tenth_of_a_pixel(runs):
    """The issue's bound, on the points where both routes sample the same ground (measured:
    153 control points, 153 tie points; -3.414 / -4.022 against -3.447 / -4.011 px)."""
    n_ref, n_tp = runs["same"]
    assert n_ref >= 100 and n_tp >= 100, runs["same"]
    ref, tp = shift(runs["same_ref"]), shift(runs["same_tp"])
    assert np.all(np.abs(ref - tp) < TENTH_PX), (ref, tp)


def test_rpcv0_shifts_across_the_parallax_within_a_tenth_of_a_pixel(runs):
    """All points of both routes: the component of the shift no height error moves
    (measured -4.815 against -4.780 px)."""
    ref = along_across(runs, shift(runs["ref"]))
    tp = along_across(runs, shift(runs["tp"]))
    assert abs(ref[1] - tp[1]) < TENTH_PX, (ref, tp)


def test_the_raw_routes_differ_along_the_parallax_by_their_samples(runs):
    """The whole point sets differ along the parallax direction (measured 0.470 px, 0.7 m of
    mean SRTM height; docs: 'The Ventoux walk-through'): each RPCV-0 is its points' mean
    offset, so the difference is the two samples' means, and it is within what each route's
    posterior says it determines."""
    ref, tp = shift(runs["ref"]), shift(runs["tp"])
    o = runs["offsets"]
    sampled = o["ref"].mean(axis=0) - o["tp"].mean(axis=0)
    # measured: they differ by 0.040 / 0.010 px of the 0.463 / 0.090 px (the adjustment
    # weighs each point by its sigmas, which are not quite equal)
    assert np.all(np.abs((ref - tp) - sampled) < 0.05), (ref - tp, sampled)
    along, across = along_across(runs, ref - tp)
    assert abs(across) < TENTH_PX
    u = o["parallax"] / np.hypot(*o["parallax"])
    s_along = np.hypot(along_sigma(runs["ref"], u), along_sigma(runs["tp"], u))
    # measured: 0.470 px against 0.341 px (1.4 sigma)
    assert abs(along) < 3 * s_along, (along, s_along)


def along_sigma(report, u):
    """The posterior sigma of the shift along ``u`` (the two parameters' sigmas; their
    correlation is small for a shift)."""
    s = sigma(report)
    return float(np.hypot(u[0] * s[0], u[1] * s[1]))


def test_the_block_ictps_are_no_worse_with_reference_control(runs):
    tp_rmse = _ictp_rmse(runs["tp"])
    both_rmse = _ictp_rmse(runs["both"])
    # measured: 2.808 m (tie points alone) and 2.808 m (with the reference control)
    assert both_rmse <= 1.01 * tp_rmse, (both_rmse, tp_rmse)


def _ictp_rmse(report):
    return float(report["statistics"]["ictp"]["left & right"]["rmse_2d"])
