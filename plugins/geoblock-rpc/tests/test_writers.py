"""RPC writers: _RPC.TXT, RPB and GeoTIFF tags read back by geoblock and by GDAL."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import _parse_rpb, _parse_rpc_txt, read_rpc
from geoblock_rpc.rpc00b import Rpc00b
from geoblock_rpc.writers import rpb_text, rpc_txt_text
from hypothesis import given, settings
from hypothesis import strategies as st
from rasterio.errors import NotGeoreferencedWarning
from rasterio.transform import RPCTransformer

import geoblock
from geoblock.errors import ModelFormatError, UnsupportedFormatError

SOURCES = [
    "gdal-autotest/gcore/data/test_rpc.txt",
    "shareloc/rpc/wv3_20.NTF",
    "rpcm/test_rpc_files/rpc_PLEIADES.xml",  # has a validity box
]
NO_BOX = {"min_long": None, "min_lat": None, "max_long": None, "max_lat": None}


def _models(data_dir: Path | None):
    models = [RpcModel.example()]
    if data_dir is not None:
        models += [geoblock.open_model(data_dir / rel) for rel in SOURCES]
    return models


def _ground(rpc: Rpc00b, n: int = 2000, seed: int = 0):
    u = np.random.default_rng(seed).uniform(-0.9, 0.9, size=(3, n))
    return (rpc.long_off + u[0] * rpc.long_scale, rpc.lat_off + u[1] * rpc.lat_scale,
            rpc.height_off + u[2] * rpc.height_scale)


def _same_projection(a: RpcModel, b: RpcModel, atol: float = 1e-9) -> None:
    lon, lat, h = _ground(a.rpc)
    np.testing.assert_allclose(np.array(b.project(lon, lat, h)),
                               np.array(a.project(lon, lat, h)), rtol=0, atol=atol)


def _close_rpc(a: Rpc00b, b: Rpc00b, rtol: float) -> None:
    da, db = a.to_dict(), b.to_dict()
    assert da.keys() == db.keys()
    for key in da:
        if da[key] is None or db[key] is None:
            assert da[key] == db[key], key
        else:
            np.testing.assert_allclose(db[key], da[key], rtol=rtol, atol=0, err_msg=key)


def _gdal_matches(model: RpcModel, rpcs, exact: bool = True) -> None:
    """GDAL's parse of what we wrote equals our model: same coefficients, and GDAL's RPC
    transformer (exact ground -> pixel/line; pixel/line = col/row + 0.5) agrees.

    GDAL hands the GeoTIFF RPC *tag* (92 doubles) back as ``%.15g`` text, so that path is
    only 15-significant-digit exact (``exact=False``); sidecar text comes back verbatim."""
    if exact:
        assert Rpc00b.from_gdal(rpcs.to_gdal()) == model.rpc.replace(**NO_BOX)
    else:
        _close_rpc(model.rpc.replace(**NO_BOX), Rpc00b.from_gdal(rpcs.to_gdal()), 1e-14)
    lon, lat, h = _ground(model.rpc)
    with RPCTransformer(rpcs) as tr:
        line, pixel = tr.rowcol(lon, lat, zs=h, op=np.positive)
    row, col = model.project(lon, lat, h)
    np.testing.assert_allclose(row, np.asarray(line) - 0.5, rtol=0, atol=1e-6)
    np.testing.assert_allclose(col, np.asarray(pixel) - 0.5, rtol=0, atol=1e-6)


def _blank_tif(path: Path, shape=(16, 16)) -> Path:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", height=shape[0], width=shape[1],
                           count=1, dtype="uint8") as ds:
            ds.write(np.arange(shape[0] * shape[1], dtype=np.uint8).reshape(1, *shape))
    return path


def _gdal_rpcs(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NotGeoreferencedWarning)
        with rasterio.open(path) as ds:
            return ds.rpcs, [Path(f).name for f in ds.files]


@pytest.fixture(params=["example", *SOURCES])
def model(request):
    if request.param == "example":
        return RpcModel.example()
    data_dir = request.getfixturevalue("data_dir")
    return geoblock.open_model(data_dir / request.param)


# ------------------------------------------------------------------------------ round trips
def test_rpc_txt_roundtrip_geoblock_and_gdal(model, tmp_path):
    out = geoblock.write_model(model, tmp_path / "img_RPC.TXT", format="rpc-txt")
    back = geoblock.open_model(out)
    assert back.rpc == model.rpc  # validity box kept too
    _same_projection(model, back)
    # GDAL picks <basename>_RPC.TXT up as the sidecar of <basename>.tif
    rpcs, files = _gdal_rpcs(_blank_tif(tmp_path / "img.tif"))
    assert "img_RPC.TXT" in files
    _gdal_matches(model, rpcs)


def test_rpb_roundtrip_geoblock_and_gdal(model, tmp_path):
    out = geoblock.write_model(model, tmp_path / "img.RPB", format="rpb")
    back = geoblock.open_model(out)
    assert back.rpc == model.rpc.replace(**NO_BOX)  # RPB has no validity box
    _same_projection(model, back)
    rpcs, files = _gdal_rpcs(_blank_tif(tmp_path / "img.tif"))
    assert "img.RPB" in files
    _gdal_matches(model, rpcs)


def test_gtiff_update_existing_keeps_pixels(model, tmp_path):
    path = _blank_tif(tmp_path / "img.tif")
    geoblock.write_model(model, path, format="gtiff")
    back = geoblock.open_model(path)
    assert back.shape == (16, 16)
    # geoblock reads the tag's doubles themselves (GDAL reports them as %.15g text)
    assert back.rpc == model.rpc.replace(**NO_BOX)
    _same_projection(model, back)
    rpcs, _ = _gdal_rpcs(path)
    _gdal_matches(model, rpcs, exact=False)
    with rasterio.open(path) as ds:
        assert ds.read(1)[3, 5] == 3 * 16 + 5


def test_gtiff_new_file_is_sparse(tmp_path):
    model = RpcModel.example().with_shape((40000, 40000))
    path = geoblock.write_model(model, tmp_path / "big.tif", format="gtiff")
    assert path.stat().st_size < 2_000_000
    back = geoblock.open_model(path)
    assert back.shape == (40000, 40000)
    _same_projection(model, back)
    with rasterio.open(path) as ds:
        assert ds.driver == "GTiff" and ds.block_shapes[0] == (256, 256)


def test_gtiff_refuses_non_geotiff(tmp_path):
    path = tmp_path / "x.tif"
    path.write_text("not a tiff")
    with pytest.raises(ModelFormatError, match="x.tif"):
        geoblock.write_model(RpcModel.example(), path, format="gtiff")


def test_writer_declines_other_models_and_formats(tmp_path):
    with pytest.raises(UnsupportedFormatError, match="nitf"):
        geoblock.write_model(RpcModel.example(), tmp_path / "a.ntf", format="nitf")


def test_text_is_full_precision():
    text = rpc_txt_text(RpcModel.example().rpc)
    assert "LINE_OFF: 4999.5\n" in text and "LINE_NUM_COEFF_5: 0.0\n" in text
    assert "\tlineScale = 5000.0;" in rpb_text(RpcModel.example().rpc)


# ------------------------------------------------------------------------------ hypothesis
_finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
_nonzero = _finite.filter(lambda v: v != 0.0)
_poly = st.lists(_finite, min_size=20, max_size=20)
_den = st.tuples(_nonzero, st.lists(_finite, min_size=19, max_size=19)).map(
    lambda t: [t[0], *t[1]])
_err = st.one_of(st.none(), st.floats(min_value=0, max_value=1e6))


@st.composite
def rpcs(draw):
    return Rpc00b(
        line_off=draw(_finite), samp_off=draw(_finite), lat_off=draw(_finite),
        long_off=draw(_finite), height_off=draw(_finite), line_scale=draw(_nonzero),
        samp_scale=draw(_nonzero), lat_scale=draw(_nonzero), long_scale=draw(_nonzero),
        height_scale=draw(_nonzero), line_num=draw(_poly), line_den=draw(_den),
        samp_num=draw(_poly), samp_den=draw(_den), err_bias=draw(_err), err_rand=draw(_err),
    )


@settings(max_examples=150, deadline=None)
@given(rpc=rpcs())
def test_text_writers_roundtrip_random_coefficients(rpc):
    where = Path("<memory>")
    assert _parse_rpc_txt(where, rpc_txt_text(rpc))[0] == rpc
    back, _, extra = _parse_rpb(where, rpb_text(rpc, "WV03", "P"))
    assert back == rpc
    assert extra["satellite_id"] == "WV03"


def test_read_rpc_of_written_files(tmp_path):
    model = RpcModel.example()
    geoblock.write_model(model, tmp_path / "m_RPC.TXT", format="rpc-txt")
    rpc, shape, extra = read_rpc(tmp_path / "m_RPC.TXT")
    assert rpc == model.rpc and shape is None and extra["format"] == "rpc-txt"
