"""Reading DigitalGlobe support data: the combined ISD XML, the separate text files, tiles,
and the errors for bad data (geoblock_quickbird.isd)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from geoblock_quickbird.isd import IsdFormatError, find_isd, read_isd
from geoblock_quickbird.model import DigitalGlobeModel

from geoblock.errors import GeoblockError
from geoblock.io import open_model
from geoblock.models.crop import CroppedModel

#: every DigitalGlobe ISD in shared/data with the physical sections: file -> (satellite,
#: rows, cols, RPB?)
PHYSICAL = {
    "stereopipeline/tests/dg_example1.xml": ("Imaginary1", 23708, 35170, True),
    "stereopipeline/tests/dg_example2.xml": ("Imaginary1", 27576, 35170, False),
    "stereopipeline/tests/dg_example3.xml": ("WV01", 54272, 35840, True),
    "stereopipeline/tests/wv_test1.xml": ("WV02", 22528, 35840, True),
    "stereopipeline/tests/wv_test2.xml": ("WV02", 20480, 35840, True),
    "rpcm/test_rpc_files/rpc_WV1.xml": ("WV01", 26828, 35180, True),
    "rpcm/test_rpc_files/rpc_WV3.xml": ("WV01", 23969, 35180, True),
}
WV1 = "stereopipeline/tests/wv_test1.xml"
WV1_TILE = "13MAY08000330-P1BS-500063426010_01_P001"


def test_asp_parse_expectations_hold_for_dg_example1(data_dir):
    """ASP TestDGCameraModel.cxx l.58-109 (MANIFEST.md)."""
    isd = read_isd(data_dir / "stereopipeline/tests/dg_example1.xml")
    assert isd.principal_distance_mm == 7949.165
    assert isd.detector_origin_mm == (0.05372, 140.71193)
    assert isd.detector_rotation_deg == 0.0 and isd.detector_pitch_mm == 0.008
    assert isd.camera_attitude == (0.0, 0.0, 0.0, 1.0)
    assert np.allclose(np.diff(isd.ephemeris_time_s), 0.02)
    assert np.allclose(np.diff(isd.attitude_time_s), 0.02)
    assert isd.ephemeris_time_s.size == isd.attitude_time_s.size == 840
    np.testing.assert_array_equal(
        isd.position_m[0], [-1.150529111070304e+06, -4.900037170821411e+06, 4.673402253879593e+06])
    # TLC (0, 0) and (23708, 1.975667): row 0 at TLCTIME, 23708 rows in 1.975667 s
    assert isd.reference_row == 0.0 and isd.reference_time_s == 0.0
    assert isd.line_period_s == pytest.approx(1.975667 / 23708, rel=1e-12)
    assert isd.shape == (23708, 35170)  # rows x cols (ASP: 35170 cols x 23708 rows)
    assert isd.has_rpb and isd.tiles == ()  # its TIL section is a placeholder ("monkey")


@pytest.mark.parametrize("name", sorted(PHYSICAL))
def test_every_dg_isd_opens_as_the_rigorous_model(data_dir, name):
    satellite, rows, cols, rpb = PHYSICAL[name]
    model = open_model(data_dir / name)
    assert isinstance(model, DigitalGlobeModel) and model.name == "dg-rigorous"
    assert model.shape == (rows, cols)
    isd = read_isd(data_dir / name)
    assert isd.satellite == satellite and isd.has_rpb == rpb
    assert model.location_accuracy_m is not None and model.location_accuracy_m > 0
    if rpb:  # the vendor RPC stays one option away, as for DIMAP v2
        assert open_model(data_dir / name, model="rpc").name == "rpc"


def test_single_tlc_entry_uses_the_average_line_rate(data_dir):
    """dg_example3: one TLC entry (row 101020 at TLCTIME), AVGLINERATE 24000 (ASP's case)."""
    isd = read_isd(data_dir / "stereopipeline/tests/dg_example3.xml")
    assert isd.reference_row == 101020.0
    assert isd.line_period_s == pytest.approx(1 / 24000)


def test_an_rpc_only_isd_opens_as_its_rpc_and_refuses_the_rigorous_model(data_dir):
    path = data_dir / "rpcm/test_rpc_files/rpc_WV2.xml"  # IMD + RPB + TIL only
    assert open_model(path).name == "rpc"
    with pytest.raises(IsdFormatError, match="EPH.*section missing"):
        open_model(path, model="dg-rigorous")


def test_aliases_name_the_same_model(data_dir):
    path = data_dir / WV1
    a = open_model(path, model="worldview")
    b = open_model(path, model="quickbird")
    assert a == b == open_model(path)


@pytest.fixture
def text_product(data_dir, tmp_path, keyword_product):
    """wv_test1 as separate .IMD/.EPH/.ATT/.GEO/.RPB/.TIL files, with its tile's image."""
    files = keyword_product(data_dir / WV1, tmp_path / "product", WV1_TILE)
    (tmp_path / "product" / f"{WV1_TILE}.NTF").write_bytes(b"")
    return files


def test_text_files_read_as_the_xml(data_dir, text_product):
    a = read_isd(data_dir / WV1)
    for section, path in text_product.items():
        b = read_isd(path)  # any one of the product's files opens it
        assert b.sources[section] == path
        for name in ("shape", "epoch", "reference_row", "line_period_s", "satellite",
                     "principal_distance_mm", "detector_origin_mm", "camera_attitude", "tiles",
                     "has_rpb"):
            assert getattr(a, name) == getattr(b, name), name
        for name in ("ephemeris_time_s", "position_m", "velocity_m_s", "quaternion",
                     "attitude_covariance", "position_covariance_m2"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_product_directory_and_tile_image_open_the_scene(data_dir, text_product):
    folder = text_product["IMD"].parent
    full = open_model(data_dir / WV1)
    assert open_model(folder) == full
    tile = open_model(folder / f"{WV1_TILE}.NTF")
    assert isinstance(tile, CroppedModel) and tile.shape == full.shape
    assert open_model(text_product["RPB"], model="rpc").name == "rpc"


def test_tiles_map_to_full_image_rows_and_columns(data_dir, text_product):
    """A two-tile product: the second tile's pixel (r, c) is the scene's (r + 11264, c)."""
    til = text_product["TIL"]
    text = til.read_text()
    head, tile = text.split("BEGIN_GROUP = TILE_1")
    tile = "BEGIN_GROUP = TILE_1" + tile.replace("\nEND;\n", "\n")
    first = tile.replace("LRRowOffset = 22527", "LRRowOffset = 11263")
    second = (tile.replace("TILE_1", "TILE_2").replace("ULRowOffset = 0", "ULRowOffset = 11264")
              .replace("_P001.NTF", "_P002.NTF"))
    til.write_text(head.replace("numTiles = 1", "numTiles = 2") + first + second + "END;\n")
    folder = til.parent
    (folder / f"{WV1_TILE[:-1]}2.NTF").write_bytes(b"")
    isd = read_isd(folder)
    assert [t.offset for t in isd.tiles] == [(0, 0), (11264, 0)]
    assert [t.shape for t in isd.tiles] == [(11264, 35840), (11264, 35840)]
    full = open_model(folder)
    second_model = open_model(folder / f"{WV1_TILE[:-1]}2.NTF")
    g = full.backproject([11300.0, 20000.0], [100.0, 30000.0], 3000.0)
    p = second_model.project(g.lon, g.lat, 3000.0)
    np.testing.assert_allclose(p.row, [11300.0 - 11264, 20000.0 - 11264], atol=1e-6)
    np.testing.assert_allclose(p.col, [100.0, 30000.0], atol=1e-6)


@pytest.mark.parametrize("section, old, new, field", [
    ("EPH", "numPoints = 1291;", "numPoints = 1290;", "EPH.NUMPOINTS"),
    ("ATT", "(1.000000000000000e+00, -3.215719468520623e-01",
     "(1.000000000000000e+00, -9.215719468520623e-01", "ATT.ATTLIST[0]"),
    ("IMD", "numRows = 22528;", "numRows = many;", "IMD.NUMROWS"),
    ("GEO", "detPitch = 8.000000000000000e-03;", "detPitch = 0;", "DETPITCH"),
    ("TIL", "LRRowOffset = 22527;", "LRRowOffset = 22528;", "LRROWOFFSET"),
    ("IMD", "TLCTime = 2013-05-08T00:03:30.536775Z;", "TLCTime = 2013-05-08T00:03:31.536775Z;",
     "FIRSTLINETIME"),
])
def test_bad_support_data_name_the_file_and_field(text_product, section, old, new, field):
    path = text_product[section]
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(IsdFormatError) as info:
        open_model(path.parent)
    assert path.name in str(info.value) and field in str(info.value)


def test_truncated_files_give_geoblock_errors(text_product):
    """Every cut of the EPH and GEO files is refused with a GeoblockError, never a traceback
    from the parser, and never a model from part of the data."""
    for section in ("EPH", "GEO", "IMD"):
        path = text_product[section]
        whole = path.read_bytes()
        for cut in np.linspace(0, len(whole) - 8, 25).astype(int):
            path.write_bytes(whole[:cut])
            with pytest.raises(GeoblockError):
                open_model(path.parent, model="dg-rigorous")
        path.write_bytes(whole)


def test_a_directory_with_two_products_is_refused_naming_them(data_dir, tmp_path):
    for name in ("a.xml", "b.xml"):
        shutil.copy(data_dir / WV1, tmp_path / name)
    with pytest.raises(IsdFormatError, match="2 products"):
        find_isd(tmp_path)
