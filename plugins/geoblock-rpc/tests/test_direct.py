"""The vendor's direct model of DIMAP RPCs (issue 26, item 9): read, evaluated as shareloc's
``compute_rational_function_polynomial`` does (CNES/shareloc ``shareloc/geomodels/rpc.py``,
``direct_loc_h(..., using_direct_coef=True)``), and compared with the inverse model iterated
(what ``RpcModel.backproject`` uses)."""

from __future__ import annotations

import re
import shutil
import warnings

import numpy as np
import pytest

from geoblock import Status
from geoblock.errors import ModelFormatError
from geoblock_rpc import RpcModel
from geoblock_rpc.direct import DirectModelWarning, read_direct_rfm

#: product -> bound on the largest disagreement (pixels, 9 x 9 x 3 grid of the image box;
#: measured 0.0018, 0.0024, 0.0045, 0.0024, 0.0045, 0.0086, 0.0018, 0.0020, 0.0222 in order)
PRODUCTS = {
    "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML": 0.002,
    "shareloc/rpc/RPC_PHR1B_P_201709281038045_SEN_PRG_FC_178608-001.XML": 0.003,
    "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML": 0.005,
    "shareloc/rpc/RPC_P1BP--2017092838284574CP.XML": 0.003,
    "shareloc/rpc/RPC_P1BP--2017092838319324CP.XML": 0.005,
    "shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML": 0.009,
    "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML": 0.002,
    "rpcm/test_rpc_files/rpc_PLEIADES.xml": 0.0021,
    "rpcm/test_rpc_files/rpc_SPOT6.xml": 0.023,
}
OISE = "shareloc/rpc/phr_oise/RPC_PHR1A_P_202503191043438_SEN_7342362101-1.XML"


@pytest.mark.parametrize("rel", sorted(PRODUCTS))
def test_direct_agrees_with_the_iterated_inverse(data_dir, rel):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DirectModelWarning)
        direct = read_direct_rfm(data_dir / rel)
    assert direct.inverse_agreement_px() <= PRODUCTS[rel]
    # and the ground points themselves, against RpcModel.backproject (the inverse iterated)
    q = direct.rpc
    u = np.linspace(-0.9, 0.9, 5)
    r, c = np.meshgrid(q.line_off + u * q.line_scale, q.samp_off + u * q.samp_scale)
    (lon, lat, h), status = direct.backproject_with_status(r, c, q.height_off)
    (lon2, lat2, _), status2 = RpcModel(q).backproject_with_status(r, c, q.height_off)
    assert (status == 0).all() and (status2 == 0).all() and (h == q.height_off).all()
    metres = np.hypot((lon - lon2) * np.cos(np.radians(lat)), lat - lat2) * 111_320.0
    assert metres.max() < 0.05


def test_direct_at_the_normalisation_centre_is_the_files_constant_terms(data_dir):
    """At (LINE_OFF, SAMP_OFF, HEIGHT_OFF) every term but the first is 0: lon is LONG_OFF +
    LONG_SCALE * SAMP_NUM_COEFF_1 / SAMP_DEN_COEFF_1 of the file's Direct_Model (and lat from
    LINE_*), which pins the coefficient naming and the 1-based offsets."""
    path = data_dir / next(iter(PRODUCTS))
    text = path.read_text()
    direct_block = text[text.index("<Direct_Model>"):text.index("</Direct_Model>")]

    def value(tag, block=text):
        return float(re.search(f"<{tag}>([^<]+)</{tag}>", block)[1])

    row0, col0 = value("LINE_OFF") - 1.0, value("SAMP_OFF") - 1.0
    lon, lat, _ = read_direct_rfm(path).backproject(row0, col0, value("HEIGHT_OFF"))
    assert lon == pytest.approx(value("LONG_OFF") + value("LONG_SCALE") * value(
        "SAMP_NUM_COEFF_1", direct_block) / value("SAMP_DEN_COEFF_1", direct_block), abs=1e-12)
    assert lat == pytest.approx(value("LAT_OFF") + value("LAT_SCALE") * value(
        "LINE_NUM_COEFF_1", direct_block) / value("LINE_DEN_COEFF_1", direct_block), abs=1e-12)


def test_a_disagreeing_direct_model_is_reported(data_dir):
    """shareloc's 2025 Oise product: its direct model is 135 px off its inverse model at the
    first column (linear in the column, 0 at the last), measured here."""
    with pytest.warns(DirectModelWarning, match=r"RPC_PHR1A_P_.*disagrees .* by up to 13\d px"):
        direct = read_direct_rfm(data_dir / OISE)
    assert 130 < direct.inverse_agreement_px() < 140


def test_domain_and_invalid_points(data_dir):
    direct = read_direct_rfm(data_dir / next(iter(PRODUCTS)))
    q = direct.rpc
    far = q.line_off + 2 * q.line_scale
    (lon, lat, h), status = direct.backproject_with_status([far, np.nan], [q.samp_off] * 2, 0.0)
    assert list(status) == [Status.OUT_OF_DOMAIN, Status.INVALID_INPUT]
    assert np.isnan(lon).all() and np.isnan(lat).all() and np.isnan(h).all()


def test_files_without_a_direct_model(data_dir, tmp_path):
    with pytest.raises(ModelFormatError, match=r"ossim-kwl RPC has no direct model"):
        read_direct_rfm(data_dir / "shareloc/rpc/phr_ventoux/left_image.geom")
    src = data_dir / next(iter(PRODUCTS))
    text = src.read_text().replace("<SAMP_DEN_COEFF_3>", "<SAMP_DEN_COEFF_X>", 1)
    text = text.replace("</SAMP_DEN_COEFF_3>", "</SAMP_DEN_COEFF_X>", 1)
    bad = tmp_path / src.name
    bad.write_text(text)
    with pytest.raises(ModelFormatError, match=r"Direct_Model/SAMP_DEN_COEFF_3"):
        read_direct_rfm(bad)
    shutil.copy(src, tmp_path / "RPC_copy.XML")
    assert read_direct_rfm(tmp_path / "RPC_copy.XML").rpc.line_off == RpcModel(
        read_direct_rfm(src).rpc).rpc.line_off
