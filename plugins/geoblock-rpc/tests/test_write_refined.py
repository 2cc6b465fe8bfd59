"""Writing a refined RPC (ImageCorrection around an RpcModel) as RPC files."""

from __future__ import annotations

import numpy as np
import pytest
from geoblock_rpc import RpcModel

import geoblock
from geoblock.errors import GeoblockWarning, ModelFormatError


def _agree(a, b, n=2000):
    rng = np.random.default_rng(0)
    rows, cols = a.shape
    r, c = rng.uniform(0, rows - 1, n), rng.uniform(0, cols - 1, n)
    g = a.backproject(r, c, rng.uniform(*a.height_range, n))
    row, col = b.project(g.lon, g.lat, g.h)
    return float(np.max(np.hypot(row - r, col - c)))


@pytest.mark.parametrize("fmt,name", [("rpc-txt", "m_RPC.TXT"), ("rpb", "m.RPB")])
def test_rpcv0_folds_exactly_and_silently(tmp_path, fmt, name):
    refined = geoblock.ImageCorrection(RpcModel.example(), 0, [2.5, -1.25])
    with pytest.warns(GeoblockWarning, match="exact") as with_warning:
        geoblock.write_model(refined, tmp_path / name, format=fmt)
    assert with_warning
    written = geoblock.open_model(tmp_path / name)
    assert isinstance(written, RpcModel)
    assert written.rpc.line_off == RpcModel.example().rpc.line_off + 2.5
    assert _agree(refined, written) < 1e-7  # localisation tolerance 1e-8 px included


def test_order_2_is_refitted_with_the_error_reported(tmp_path):
    refined = geoblock.ImageCorrection(
        RpcModel.example(), 2, [1.0, 0.5, -0.3, 0.2, -0.1, 0.05, -1.0, 0.2, 0.4, -0.1, 0.1, 0.02]
    )
    with pytest.warns(GeoblockWarning, match=r"refit\): max error .* px"):
        geoblock.write_model(refined, tmp_path / "m_RPC.TXT", format="rpc-txt")
    assert _agree(refined, geoblock.open_model(tmp_path / "m_RPC.TXT")) < 1e-3


def test_a_refit_worse_than_the_limit_is_refused(tmp_path):
    refined = geoblock.ImageCorrection(
        RpcModel.example(), 2, [1.0, 0.5, -0.3, 0.2, -0.1, 0.05, -1.0, 0.2, 0.4, -0.1, 0.1, 0.02]
    )
    with pytest.raises(
        ModelFormatError, match="does not fold into RPC00B exactly.*write the model as JSON"
    ):
        geoblock.write_model(refined, tmp_path / "m_RPC.TXT", format="rpc-txt",
                             max_refit_error_px=1e-15)
    assert not (tmp_path / "m_RPC.TXT").exists()


def test_non_rpc_models_are_fitted(tmp_path):
    from geoblock.testing.synthetic import AffineCamera

    with pytest.warns(geoblock.errors.GeoblockWarning, match="FITTED"):
        geoblock.write_model(AffineCamera.example(), tmp_path / "m_RPC.TXT", format="rpc-txt")
    assert geoblock.open_model(tmp_path / "m_RPC.TXT").name == "rpc"
