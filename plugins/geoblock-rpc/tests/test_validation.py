"""Impossible RPC metadata is refused when a model is built, naming the file and the field, and
points far outside any domain never come back CONVERGED (issue 12, item 3)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from geoblock_rpc import _kernels, _small
from geoblock_rpc.model import PARALLEL_MIN_POINTS, RpcModel
from geoblock_rpc.rpc00b import Rpc00b

import geoblock
from geoblock.errors import GeoblockError, ModelFormatError
from geoblock.typing import Status


def _example_rpc() -> Rpc00b:
    return RpcModel.example().rpc.replace(source="scene_RPC.TXT")


def _term(name: str, index: int, value: float) -> dict:
    coef = np.array(getattr(_example_rpc(), name))
    coef[index] = value
    return {name: coef}


#: case -> (changes to the example RPC, fragments of the message besides the source)
IMPOSSIBLE = {
    "latitude offset 501": ({"lat_off": 501.0}, ["LAT_OFF", "501"]),
    "longitude offset 1e308": ({"long_off": 1e308}, ["LONG_OFF"]),
    "longitude offset -200": ({"long_off": -200.0}, ["LONG_OFF"]),
    "height offset 1e308": ({"height_off": 1e308}, ["HEIGHT_OFF"]),
    "line offset 1e308": ({"line_off": 1e308}, ["LINE_OFF"]),
    "sample offset -1e308": ({"samp_off": -1e308}, ["SAMP_OFF"]),
    "line scale 1e308": ({"line_scale": 1e308}, ["LINE_SCALE"]),
    "sample scale 1e-9": ({"samp_scale": 1e-9}, ["SAMP_SCALE"]),
    "latitude scale 500": ({"lat_scale": 500.0}, ["LAT_SCALE"]),
    "longitude scale 1e-300": ({"long_scale": 1e-300}, ["LONG_SCALE"]),
    "height scale 1e308": ({"height_scale": 1e308}, ["HEIGHT_SCALE"]),
    "denominator term -9.9e231": (_term("line_den", 7, -9.9e231), ["LINE_DEN_COEFF_8"]),
    "numerator term 1e308": (_term("samp_num", 3, 1e308), ["SAMP_NUM_COEFF_4"]),
    "image box 50 ground scales off": (_term("line_num", 0, 50.0),
                                       ["image box centre", "map to ground nowhere"]),
    "image box 5 ground scales off": (_term("line_num", 0, 5.0),
                                      ["image box centre", "ground scales away", "within 3"]),
    "tiny denominator constant": ({"samp_den": np.array(_example_rpc().samp_den) * 1e-6},
                                  ["ground sample distance", "5.01e-07"]),
    # another field's value in a scale (the fuzz's scale swaps): one axis 44x longer
    "latitude scale swapped for the longitude offset": ({"lat_scale": 1.0},
                                                        ["ground sample distance", "anisotropy"]),
    "ground sample distance of 500 km": ({"line_num": np.array(_example_rpc().line_num) * 1e-6,
                                          "samp_num": np.array(_example_rpc().samp_num) * 1e-6},
                                         ["ground sample distance", "100000 m"]),
    "error bias 1e9 m": ({"err_bias": 1e9}, ["ERR_BIAS"]),
    "validity box beside the ground box": ({"min_long": 8.0, "max_long": 8.1, "min_lat": 43.6,
                                            "max_lat": 43.8}, ["does not overlap the ground box"]),
    "empty validity box": ({"min_long": 7.05, "max_long": 7.05, "min_lat": 43.6,
                            "max_lat": 43.8}, ["validity box"]),
    "latitude of the box 95": ({"min_long": 7.0, "max_long": 7.1, "min_lat": 43.6,
                                "max_lat": 95.0}, ["MAX_LAT"]),
}


@pytest.mark.parametrize("case", sorted(IMPOSSIBLE))
def test_impossible_fields_are_refused_when_the_model_is_built(case):
    changes, fragments = IMPOSSIBLE[case]
    rpc = _example_rpc().replace(**changes)  # the coefficients alone may hold anything finite
    with pytest.raises(ModelFormatError) as info:
        RpcModel(rpc, (10000, 12000))
    for fragment in ["scene_RPC.TXT", *fragments]:
        assert fragment in str(info.value)


#: case -> changes to the example RPC that real files have and rules of issue 12 refused
POSSIBLE = {
    # a validity box overlapping the ground box need not hold its centre (a crop's RPC)
    "validity box off the centre": {"min_long": 7.06, "max_long": 7.2, "min_lat": 43.71,
                                    "max_lat": 43.8},
    # s2p/rpcm/CARS crop RPC: image box re-normalised to a 1024 px crop at the scene's corner,
    # the ground box kept: the ground centre projects 8.8 crop scales from the crop centre
    "crop re-normalised": {"line_off": 511.5, "line_scale": 512.0,
                           "line_num": np.array(_example_rpc().line_num) * 5000.0 / 512.0
                           + np.array(_example_rpc().line_den) * 4487.5 / 512.0},
}


@pytest.mark.parametrize("case", sorted(POSSIBLE))
def test_possible_fields_are_accepted(case):
    RpcModel(_example_rpc().replace(**POSSIBLE[case]), (1024, 12000))


@pytest.mark.parametrize(("field", "value"), [("err_bias", math.inf), ("err_rand", math.nan),
                                              ("err_bias", -3.0), ("max_lat", math.inf)])
def test_non_finite_or_negative_accuracies_are_refused(field, value):
    with pytest.raises(ModelFormatError, match=rf"scene_RPC\.TXT: {field.upper()}"):
        _example_rpc().replace(**{field: value})


def test_minus_one_still_means_an_unknown_accuracy():
    rpc = _example_rpc().replace(err_bias=-1.0, err_rand=-1)
    assert rpc.err_bias is None and rpc.err_rand is None
    RpcModel(rpc, (10000, 12000))


@pytest.mark.parametrize("shape", [(10000.5, 12000), (1e308, 12000), (0, 12000), (10000, -1),
                                   (10000, math.nan), (True, 12000), (10000,), "ab"])
def test_impossible_image_shapes_are_refused(shape):
    with pytest.raises(ModelFormatError, match=r"scene_RPC\.TXT: image"):
        RpcModel(_example_rpc(), shape)


@pytest.mark.parametrize("limits", [(math.inf, 5.0), (1.5, math.nan), (0.5, 5.0)])
def test_domain_limits_must_be_finite(limits):
    with pytest.raises(ModelFormatError, match="domain_limit and height_limit"):
        RpcModel(_example_rpc(), (10000, 12000), domain_limit=limits[0], height_limit=limits[1])


# ------------------------------------------------------------------------ from files and JSON
@pytest.mark.parametrize(("old", "new", "field"), [
    ("LAT_OFF: +43.70", "LAT_OFF: +501.0", "LAT_OFF"),
    ("LINE_OFF: +4999.5", "LINE_OFF: 1e308", "LINE_OFF"),
    ("ERR_BIAS: 5.0", "ERR_BIAS: inf", "ERR_BIAS"),
])
def test_rpc_txt_with_impossible_values_names_file_and_field(tmp_path, old, new, field):
    path = tmp_path / "scene_RPC.TXT"
    geoblock.write_model(RpcModel.example(), path, format="rpc-txt")
    text = path.read_text()
    key = old.split(":")[0]
    line = next(ln for ln in text.splitlines() if ln.startswith(key + ":"))
    assert float(line.split(":")[1].split()[0]) == float(old.split(":")[1])
    path.write_text(text.replace(line, new))
    with pytest.raises(GeoblockError) as info:
        geoblock.open_model(path)
    assert str(path) in str(info.value) and field in str(info.value)


def test_model_json_with_impossible_values_names_file_and_field(tmp_path):
    path = geoblock.write_model(RpcModel.example(), tmp_path / "scene.json")
    data = json.loads(path.read_text())
    data["rpc"]["lat_off"] = 501.0
    path.write_text(json.dumps(data))
    with pytest.raises(GeoblockError) as info:
        geoblock.open_model(path)
    assert str(path) in str(info.value) and "LAT_OFF" in str(info.value)
    data["rpc"]["lat_off"] = 43.7
    data["shape"] = [10000.5, 12000]
    path.write_text(json.dumps(data))
    with pytest.raises(GeoblockError, match="image rows 10000.5"):
        geoblock.open_model(path)


def test_ossim_sizes_that_are_not_whole_numbers_are_refused(data_dir, tmp_path):
    source = data_dir / "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom"
    if not source.is_file():
        pytest.skip(f"{source} not found")
    text = source.read_text()
    assert "number_lines:  22940" in text
    mutant = tmp_path / source.name
    mutant.write_text(text.replace("number_lines:  22940", "number_lines:  22940.5"))
    with pytest.raises(ModelFormatError) as info:
        geoblock.open_model(mutant)
    assert str(mutant) in str(info.value) and "number_lines" in str(info.value)


# ------------------------------------------------------------------------ out of domain
FAR = [(1e300, 43.7, 500.0), (-1e300, 43.7, 500.0), (7.05 + 360.0 * 1e6, 43.7, 500.0),
       (7.05, 1e300, 500.0), (7.05, 43.7, 1e300), (7.05, 43.7, -1e6), (1e300, 1e300, 1e300),
       (367.05, 43.7, 500.0), (7.05, 90.5, 500.0)]


@pytest.mark.parametrize("n", [len(FAR), PARALLEL_MIN_POINTS + 3])
def test_points_far_outside_any_domain_are_never_converged(n):
    rpc = RpcModel.example().rpc.replace(lat_scale=2.0, long_scale=3.3)  # GSD 44 m both ways
    model = RpcModel(rpc, (10000, 12000))
    lon, lat, h = (np.resize(np.array(v, float), n) for v in zip(*FAR, strict=True))
    (row, col), status = model.project_with_status(lon, lat, h)
    # 367.05 is 7.05: a real longitude, inside; every other point is no place of the model
    inside = np.resize(np.array([p == (367.05, 43.7, 500.0) for p in FAR]), n)
    assert np.all(status[~inside] == Status.OUT_OF_DOMAIN)
    assert np.isnan(row[~inside]).all() and np.isnan(col[~inside]).all()
    assert np.all(status[inside] == Status.CONVERGED)


@pytest.mark.parametrize("kernel", [_kernels.project, _kernels.project_serial,
                                    _small.project])
def test_both_kernels_refuse_huge_longitudes_before_wrapping(kernel):
    model = RpcModel.example()
    lon = np.array([7.05, 1e300, -1e300, 1e20, 7.05 + 720.0])
    lat = np.full(5, 43.7)
    h = np.full(5, 500.0)
    row, col, status = np.empty(5), np.empty(5), np.empty(5, np.uint8)
    kernel(lon, lat, h, model._prm, model._coef, row, col, status)
    assert list(status) == [Status.CONVERGED] + [Status.OUT_OF_DOMAIN] * 4


def test_backprojection_far_outside_the_height_range_is_out_of_domain():
    model = RpcModel.example()
    _, status = model.backproject_with_status([5000.0] * 3, [6000.0] * 3, [500.0, 1e300, -1e6])
    assert list(status) == [Status.CONVERGED, Status.OUT_OF_DOMAIN, Status.OUT_OF_DOMAIN]
