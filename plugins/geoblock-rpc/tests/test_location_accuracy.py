"""RpcModel.location_accuracy_m: the product's ERR_BIAS (RPC00B: RMS bias error per horizontal
axis, metres), as linescan models state theirs; None when the file does not tell."""

from __future__ import annotations

import pytest
from geoblock_rpc.model import RpcModel
from geoblock_rpc.writers import write_rpc_txt

import geoblock


@pytest.mark.parametrize(("rel", "bias_m"), [
    ("gdal-autotest/gcore/data/md_dg.RPB", 1.49),  # errBias = 1.49; errRand = 0.58
    ("gdal-autotest/gcore/data/test_rpc.txt", 0.31),  # ERR_BIAS: 0000.31 meters
    ("rpcm/test_rpc_files/rpc_IKONOS.txt", 3.31),
    ("rpcm/test_rpc_files/rpc_WV2.xml", 26.68),  # DG ISD <RPB><ERRBIAS>
])
def test_err_bias_of_real_files(data_dir, rel, bias_m):
    path = data_dir / rel
    if not path.exists():
        pytest.skip(f"{path} not in the test data")
    model = geoblock.open_model(path)
    assert isinstance(model, RpcModel)
    assert model.location_accuracy_m == pytest.approx(bias_m, abs=1e-12)


@pytest.mark.parametrize("rel", [
    # DIMAP v2: ERR_BIAS_ROW/COL (pixels) and ERR_BIAS_X/Y (degrees) are the RFM's fit
    # residuals, not a location accuracy
    "rpcm/test_rpc_files/rpc_PLEIADES.xml",
    "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML",
    "shareloc/rpc/phr_ventoux/left_image.geom",  # OSSIM keyword list, bias_error: 0
    "rpcm/test_rpc_files/rpc_PLANET_L1B.txt",  # no ERR_BIAS line
])
def test_no_stated_accuracy_is_none(data_dir, rel):
    path = data_dir / rel
    if not path.exists():
        pytest.skip(f"{path} not in the test data")
    assert geoblock.open_model(path).location_accuracy_m is None


def test_minus_one_means_unknown_and_survives_a_round_trip(tmp_path):
    model = RpcModel.example()
    assert model.location_accuracy_m == model.rpc.err_bias == 5.0
    unknown = RpcModel(model.rpc.replace(err_bias=-1.0), model.shape)
    assert unknown.location_accuracy_m is None
    assert RpcModel(model.rpc.replace(err_bias=0.0), model.shape).location_accuracy_m is None
    for m, expected in ((model, 5.0), (unknown, None)):  # -1 written when unknown
        path = write_rpc_txt(m, tmp_path / f"{expected}_RPC.TXT")
        assert geoblock.open_model(path).location_accuracy_m == expected
    assert RpcModel.from_dict(model.to_dict()).location_accuracy_m == 5.0
