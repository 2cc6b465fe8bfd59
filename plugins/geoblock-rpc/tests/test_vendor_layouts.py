"""Vendor layouts GDAL reads (issue 26, item 5): JAXA's ALOS fixed-width RPC, a DigitalGlobe
``.IMD`` given alone, RPC00A term order (NITF TRE and OSSIM ``.geom`` type A), and a raster
whose RPC metadata cannot be parsed.

RPC00A order is OSSIM's ``ossimRpcModel::polynomial`` type ``A`` (``src/projection/
ossimRpcModel.cpp`` l. 645-652 at ossimlabs/ossim ``bcf2f33``), written out independently below
(:func:`_ossim_a`); GDAL's NITF reader (``NITFReadRPC00B``) applies the same index table the
other way round, which the tests measure.
"""

from __future__ import annotations

import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
import rasterio.errors
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer

import geoblock
from geoblock.errors import ModelFormatError
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import RPC00A_TO_B, read_rpc

ALOS = "gdal-autotest/gcore/data/alos/RPC-md_alos.txt"
DG = "gdal-autotest/gcore/data/md_dg"
GEOM = "shareloc/rpc/phr_ventoux/left_image.geom"


def _ossim_a(rpc_a: dict, lon, lat, h):
    """(row, col) of an RPC whose coefficients are in RPC00A order, by OSSIM's type-A
    polynomial: 1 L P H LP LH PH LPH L2 P2 H2 L3 L2P L2H LP2 P3 P2H LH2 PH2 H3."""
    L = (lon - rpc_a["long_off"]) / rpc_a["long_scale"]
    P = (lat - rpc_a["lat_off"]) / rpc_a["lat_scale"]
    H = (h - rpc_a["height_off"]) / rpc_a["height_scale"]
    one = np.ones_like(L)
    terms = np.stack([one, L, P, H, L * P, L * H, P * H, L * P * H, L * L, P * P, H * H,
                      L ** 3, L * L * P, L * L * H, L * P * P, P ** 3, P * P * H, L * H * H,
                      P * H * H, H ** 3])

    def ratio(num, den):
        return np.tensordot(num, terms, 1) / np.tensordot(den, terms, 1)

    row = rpc_a["line_off"] + rpc_a["line_scale"] * ratio(rpc_a["line_num"], rpc_a["line_den"])
    col = rpc_a["samp_off"] + rpc_a["samp_scale"] * ratio(rpc_a["samp_num"], rpc_a["samp_den"])
    return row, col


def _grid(rpc, n=7):
    u = np.linspace(-1, 1, n)
    lon, lat, h = np.meshgrid(u, u, u, indexing="ij")
    return (rpc.long_off + 0.9 * lon.ravel() * rpc.long_scale,
            rpc.lat_off + 0.9 * lat.ravel() * rpc.lat_scale,
            rpc.height_off + 0.9 * h.ravel() * rpc.height_scale)


def _gdal_project(rpcs: RPC, lon, lat, h):
    """GDAL's ground -> (row, col), geoblock's convention (GDAL's pixel/line less 0.5)."""
    with RPCTransformer(rpcs) as tr:
        line, pixel = tr.rowcol(lon, lat, zs=h, op=np.positive)
    return np.asarray(line) - 0.5, np.asarray(pixel) - 0.5


def _quiet_open(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        return rasterio.open(path)


def _raster(path: Path, **options) -> Path:
    args = ["gdal_create", "-q", "-of", options.pop("driver", "GTiff"), "-outsize", "20", "20",
            "-bands", "1"]
    for key, value in options.items():
        args += ["-co", f"{key}={value}"]
    subprocess.run([*args, str(path)], check=True, capture_output=True)
    return path


# ------------------------------------------------------------------ ALOS
def test_alos_fixed_width_rpc_is_read_as_gdal_reads_it(data_dir, tmp_path):
    """Before: 'named like an RPC file but holds no RPC coefficients'."""
    rpc, shape, extra = read_rpc(data_dir / ALOS)
    assert extra["format"] == "alos" and shape is None
    # GDAL's own reading: the RPC-*.txt beside an IMG-*.tif with summary.txt (reader_alos.cpp)
    shutil.copy(data_dir / ALOS, tmp_path)
    (tmp_path / "summary.txt").write_text('Lbi_Satellite="ALOS"\n')
    image = _raster(tmp_path / "IMG-md_alos.tif")
    with _quiet_open(image) as ds:
        gdal_rpcs = ds.rpcs
    assert gdal_rpcs is not None
    assert gdal_rpcs.line_off == rpc.line_off == 4000.0 and rpc.samp_off == 3639.0
    assert (rpc.lat_off, rpc.long_off, rpc.height_off) == (55.8151, 32.0758, 3000.0)
    assert np.array_equal(rpc.line_num, gdal_rpcs.line_num_coeff)
    assert np.array_equal(rpc.samp_den, gdal_rpcs.samp_den_coeff)
    lon, lat, h = _grid(rpc)
    (row, col), status = RpcModel(rpc).project_with_status(lon, lat, h)
    g_row, g_col = _gdal_project(gdal_rpcs, lon, lat, h)
    assert (status == 0).all()
    assert np.max(np.abs(row - g_row)) < 1e-9 and np.max(np.abs(col - g_col)) < 1e-9


def test_alos_bad_field_is_named(data_dir, tmp_path):
    text = (data_dir / ALOS).read_text()
    bad = tmp_path / "RPC-bad.txt"
    bad.write_text(text[:11] + "+55.81x1" + text[19:])
    with pytest.raises(ModelFormatError, match=r"ALOS RPC field LAT_OFF \(characters 12-19\)"):
        read_rpc(bad)
    short = tmp_path / "RPC-short.txt"
    short.write_text(text[:1100 - 90] + "\n")
    with pytest.raises((ModelFormatError, geoblock.errors.UnsupportedFormatError)):
        read_rpc(short)


# ------------------------------------------------------------------ DigitalGlobe .IMD
def test_dg_imd_alone_opens_its_rpb(data_dir, tmp_path):
    """Before: 'no geoblock plugin can read this file'."""
    rpc, shape, extra = read_rpc(data_dir / f"{DG}.IMD")
    rpb, _, _ = read_rpc(data_dir / f"{DG}.RPB")
    assert extra["format"] == "dg-imd" and extra["rpb_file"].endswith("md_dg.RPB")
    assert shape == (50, 50) and extra["satellite_id"] == "WV03"
    assert rpc.to_dict() == rpb.to_dict()
    alone = Path(shutil.copy(data_dir / f"{DG}.IMD", tmp_path))
    with pytest.raises(ModelFormatError, match=r"md_dg\.IMD: .*its \.RPB \(md_dg\.RPB\)"):
        geoblock.open_model(alone)


# ------------------------------------------------------------------ RPC00A
def test_rpc00a_table_is_ossims_type_a():
    """The table against the term lists themselves (not against its own inverse)."""
    a = "1 L P H LP LH PH LPH LL PP HH LLL LLP LLH LPP PPP PPH LHH PHH HHH".split()
    b = "1 L P H LP LH PH LL PP HH LPH LLL LPP LHH LLP PPP PHH LLH PPH HHH".split()
    assert [b.index(term) for term in a] == list(RPC00A_TO_B)


def _a_order(b_coefficients):
    return np.asarray(b_coefficients)[list(RPC00A_TO_B)]


def test_ossim_geom_type_a_follows_ossims_polynomial(data_dir, tmp_path):
    """A .geom of type A whose coefficients are the Ventoux RPC's in A order: geoblock's model
    projects as OSSIM's type-A polynomial does. Before: 1.5 px off (cubic terms left in B
    order)."""
    rpc_b, _, _ = read_rpc(data_dir / GEOM)
    lines = []
    for line in (data_dir / GEOM).read_text().splitlines():
        key, sep, _ = line.partition(":")
        name = key.strip()
        if name == "polynomial_format":
            line = f"{key}:  A"
        elif sep and name[:-3] in ("line_num_coeff", "line_den_coeff", "samp_num_coeff",
                                   "samp_den_coeff"):
            poly = {"line_num_coeff": "line_num", "line_den_coeff": "line_den",
                    "samp_num_coeff": "samp_num", "samp_den_coeff": "samp_den"}[name[:-3]]
            value = float(_a_order(getattr(rpc_b, poly))[int(name[-2:])])
            line = f"{key}:  {value!r}"
        lines.append(line)
    geom_a = tmp_path / "type_a.geom"
    geom_a.write_text("\n".join(lines) + "\n")
    rpc, _, extra = read_rpc(geom_a)
    assert extra["polynomial_format"] == "A"
    d = rpc_b.to_dict()
    rpc_a = {**d, **{k: _a_order(d[k]) for k in ("line_num", "line_den", "samp_num",
                                                 "samp_den")}}
    lon, lat, h = _grid(rpc)
    (row, col), _ = RpcModel(rpc).project_with_status(lon, lat, h)
    o_row, o_col = _ossim_a(rpc_a, lon, lat, h)
    assert np.max(np.hypot(row - o_row, col - o_col)) < 1e-8


def test_nitf_rpc00a_tre_follows_ossims_polynomial(data_dir, tmp_path):
    """A NITF whose RPC00A TRE carries the ALOS record's coefficients (read as A order):
    geoblock projects as OSSIM's type-A polynomial; GDAL's reordering is measured off it."""
    record = (data_dir / ALOS).read_text().split("\n")[0][:1026]
    nitf = _raster(tmp_path / "a.ntf", driver="NITF", TRE=f"RPC00A=1" + "0001.00" + "0000.50"
                   + record)
    model = geoblock.open_model(nitf)
    rpc = model.rpc
    assert (rpc.err_bias, rpc.err_rand) == (1.0, 0.5)
    alos, _, _ = read_rpc(data_dir / ALOS)  # the same numbers, as stored (A order here)
    rpc_a = alos.to_dict()
    lon, lat, h = _grid(rpc)
    (row, col), _ = model.project_with_status(lon, lat, h)
    o_row, o_col = _ossim_a(rpc_a, lon, lat, h)
    assert np.max(np.hypot(row - o_row, col - o_col)) < 1e-8
    with _quiet_open(nitf) as ds:
        g_row, g_col = _gdal_project(ds.rpcs, lon, lat, h)
    off = np.hypot(g_row - o_row, g_col - o_col)
    assert off.max() > 1.0  # GDAL's reading is not OSSIM's type A (see RPC00A_TO_B)


# ------------------------------------------------------------------ unparsable metadata
def test_unparsable_raster_rpc_names_the_field_and_file(data_dir, tmp_path):
    """Before: 'no geoblock plugin can read this file (... ValueError ...)'."""
    image = _raster(tmp_path / "img.tif")
    text = (data_dir / f"{DG}.RPB").read_text().replace("lineOffset = 812;",
                                                        "lineOffset = 8x12;")
    (tmp_path / "img.RPB").write_text(text)
    with pytest.raises(ModelFormatError,
                       match=r"img\.tif: GDAL RPC metadata \(from img\.RPB\) field LINE_OFF "
                             r"must be a number, got '8x12'"):
        geoblock.open_model(image)


# ------------------------------------------------------------------ fixed-width round trip
#: a fixed-width coefficient of at most 1e-3: sign, d.dddddd, E, signed one-digit exponent
_coef = st.builds(lambda m, e: f"{m:+.6f}E{e:+d}",
                  st.floats(min_value=-9.999999, max_value=9.999999, allow_nan=False),
                  st.integers(-9, -4))


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(line_off=st.integers(1000, 99_999), samp_off=st.integers(1000, 99_999),
       lat=st.floats(-80, 80), lon=st.floats(-179, 179), h_off=st.integers(-999, 9999),
       coefficients=st.lists(_coef, min_size=80, max_size=80))
def test_alos_layout_round_trip(tmp_path, line_off, samp_off, lat, lon, h_off, coefficients):
    """Any record in the ALOS widths reads back as the numbers its fields spell (the line and
    sample scales equal, for a plausible pixel shape)."""
    # a plausible geometry: row from -latitude, column from longitude, denominators near 1
    coefficients[2], coefficients[41] = "-1.000000E+0", "+1.000000E+0"
    coefficients[20] = coefficients[60] = "+1.000000E+0"
    head = (f"{line_off:06d}{samp_off:05d}{lat:+08.4f}{lon:+09.4f}{h_off:+05d}"
            f"{line_off:06d}{line_off:05d}{'+00.2000'}{'+000.3000'}{'+0500'}")
    assert all(len(c) == 12 for c in coefficients) and len(head) == 66
    path = tmp_path / "RPC-roundtrip.txt"
    path.write_text(head + "".join(coefficients))
    rpc, _, extra = read_rpc(path)
    assert extra["format"] == "alos"
    assert (rpc.line_off, rpc.samp_off) == (line_off, samp_off)
    assert rpc.lat_off == float(f"{lat:+08.4f}") and rpc.long_off == float(f"{lon:+09.4f}")
    assert rpc.height_off == h_off
    assert np.array_equal(rpc.line_num, [float(c) for c in coefficients[:20]])
    assert np.array_equal(rpc.samp_den, [float(c) for c in coefficients[60:]])
