"""Reverse-scanned products (SCANDIRECTION Reverse) and ISDs whose RPB contradicts their physical
sections (issue 26, items 2 and 6)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from geoblock_quickbird.isd import read_isd
from geoblock_quickbird.model import (
    DEFAULT_HEIGHT_RANGE,
    RPB_DISAGREEMENT_PX,
    DigitalGlobeModel,
    RpbDisagreementWarning,
    dg_model,
    rpb_agreement,
)

from geoblock.io import open_model

#: COSI-Corr3D's WorldView-1 ISD (MANIFEST.md): SCANDIRECTION Reverse, TLC (0, 0) and
#: (25244, -1.051833 s)
REVERSE = "cosicorr3d/test_dataset/WV1.XML"
#: every DigitalGlobe ISD of shared/data with an RPB and the physical sections
WITH_RPB = [REVERSE, "rpcm/test_rpc_files/rpc_WV1.xml", "rpcm/test_rpc_files/rpc_WV3.xml",
            "stereopipeline/tests/wv_test1.xml", "stereopipeline/tests/wv_test2.xml",
            "stereopipeline/tests/dg_example1.xml", "stereopipeline/tests/dg_example3.xml"]
DG1 = "stereopipeline/tests/dg_example1.xml"


# ================================================================================ reverse scan
def test_the_reverse_scan_is_read_as_written(data_dir):
    """ASP (LinescanDGModel.cc) and COSI-Corr3D (DigitalGlobe_RSM.py, ``loc_img = -i /
    AVGLINERATE`` for a reverse scan) use the TLC as written: the line period is negative."""
    isd = read_isd(data_dir / REVERSE)
    assert isd.reference_row == 0.0 and isd.reference_time_s == 0.0
    assert isd.line_period_s == pytest.approx(-1.051833 / 25244, rel=1e-12)
    model = open_model(data_dir / REVERSE)
    assert isinstance(model, DigitalGlobeModel) and model.shape == (25600, 35840)
    assert model.line_times.reverse
    # row 0 (at FIRSTLINETIME) is the last line acquired
    times = model.line_times.time(np.array([0.0, 25599.0]))
    assert times[0] > times[1]


def test_the_reverse_scan_agrees_with_its_rpb_at_every_height(data_dir):
    """50 x 50 grid x 3 heights across the RPB's range (measured 0.081 px RMS, 0.144 px max
    at each height; docs/user-guide/digitalglobe.md)."""
    model = open_model(data_dir / REVERSE)
    rpc = open_model(data_dir / REVERSE, model="rpc")
    rows, cols = model.shape
    rr, cc = (a.ravel() for a in np.meshgrid(np.linspace(0, rows - 1, 50),
                                             np.linspace(0, cols - 1, 50), indexing="ij"))
    for h in np.linspace(*rpc.height_range, 3):
        g = rpc.backproject(rr, cc, h)
        p = model.project(g.lon, g.lat, h)
        d = np.hypot(p.row - rr, p.col - cc)
        assert np.all(np.isfinite(d))
        assert np.sqrt(np.mean(d**2)) < 0.09 and d.max() < 0.16
    assert model.height_range == rpc.height_range  # an agreeing RPB gives the heights


def test_a_single_tlc_reverse_product_uses_the_scan_direction(data_dir, tmp_path):
    """One TLC entry: the period is -1/AVGLINERATE for SCANDIRECTION Reverse (ASP's and
    COSI-Corr3D's rule); the model is the two-entry table's within 0.05 px."""
    text = (data_dir / REVERSE).read_text()
    table = re.search(r"<TLCLISTList>.*?</TLCLISTList>", text, re.DOTALL)
    assert table is not None and "<NUMTLC>2</NUMTLC>" in text
    one = (text.replace(table.group(0), "<TLCLISTList><TLCLIST>0 0</TLCLIST></TLCLISTList>")
           .replace("<NUMTLC>2</NUMTLC>", "<NUMTLC>1</NUMTLC>"))
    path = tmp_path / "WV1.XML"
    path.write_text(one)
    assert read_isd(path).line_period_s == pytest.approx(-1 / 24000, rel=1e-12)
    full, single = open_model(data_dir / REVERSE), open_model(path)
    rows, cols = full.shape
    r, c = np.meshgrid(np.linspace(0, rows - 1, 7), np.linspace(0, cols - 1, 7))
    g = full.backproject(r, c, 900.0)
    p = single.project(g.lon, g.lat, 900.0)
    assert np.max(np.hypot(p.row - r, p.col - c)) < 0.05


def test_the_reverse_scan_solves_outside_the_image_and_with_every_preset(data_dir):
    """The ground -> image search brackets the times whatever their order: points a few
    hundred rows beyond either end converge; the presets' sigmas are positive."""
    model = open_model(data_dir / REVERSE)
    rows, cols = model.shape
    rr = np.array([-300.0, 0.0, rows / 2, rows - 1.0, rows + 300.0])
    g = model.backproject(rr, np.full(5, cols / 3), 800.0)
    p, status = model.project_with_status(g.lon, g.lat, 800.0)
    assert np.all(status == 0)
    np.testing.assert_allclose(p.row, rr, atol=1e-6)
    for preset in ("dg", "physical"):
        assert np.all(model.with_parameter_set(preset).parameters.sigmas > 0)


# ====================================================================== RPB vs physical model
@pytest.mark.parametrize("name", WITH_RPB)
def test_no_real_product_warns_and_each_agrees_with_its_rpb(data_dir, name):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RpbDisagreementWarning)
        model = open_model(data_dir / name)
    agreement = rpb_agreement(model, open_model(data_dir / name, model="rpc"))
    assert agreement.n_unprojected == 0 and agreement.max_px < 1.0
    assert agreement.ground_distance_m < 1.0 and not agreement.disagrees


def _edit_rpb(text: str, old: str, new: str) -> str:
    """The ISD text with one field of its RPB section changed (the physical sections kept)."""
    head, rpb = text.split("<RPB>", 1)
    assert old in rpb
    return head + "<RPB>" + rpb.replace(old, new, 1)


def test_an_rpb_of_another_place_is_reported_naming_both(data_dir, tmp_path):
    """ASP's dg_example4.xml is dg_example1.xml with the RPB moved by 2 degrees in latitude and
    longitude: the physical model opens with a warning naming the RPB, the physical sections,
    where each puts the image and how far apart, and keeps its own heights."""
    text = (data_dir / DG1).read_text()
    text = _edit_rpb(text, "<LATOFFSET>3.974540000000000e+01", "<LATOFFSET>3.774540000000000e+01")
    text = _edit_rpb(text, "<LONGOFFSET>-1.052903000000000e+02",
                     "<LONGOFFSET>-1.032903000000000e+02")
    path = tmp_path / "dg_example4.xml"
    path.write_text(text)
    with pytest.warns(RpbDisagreementWarning) as record:
        model = open_model(path)
    message = str(record[0].message)
    assert str(path) in message and "RPB" in message
    assert "physical model (IMD, EPH, ATT, GEO" in message
    assert "282 km apart" in message and "lat 39.74599" in message and "lat 37.74599" in message
    assert "no image point for 27 of them" in message
    # the heights are not the RPB's (1644, 2918): the physical model's own default
    assert model.height_range == DEFAULT_HEIGHT_RANGE
    assert f"not the RPB's {read_isd(path).rpb_height_range}" in message
    # and the physical model itself is the genuine one
    genuine = open_model(data_dir / DG1)
    g = genuine.backproject(1000.0, 2000.0, 2000.0)
    np.testing.assert_allclose(model.project(*g), [1000.0, 2000.0], atol=1e-6)


@pytest.mark.parametrize("shift_px, warns", [(10, False), (200, True)])
def test_the_warning_gives_the_distance_in_pixels(data_dir, tmp_path, shift_px, warns):
    """An RPB moved by a few pixels agrees within the limit; by 200 px it is reported with the
    distance. A height range given by the user is kept either way."""
    text = _edit_rpb((data_dir / DG1).read_text(), "<LINEOFFSET>11856</LINEOFFSET>",
                     f"<LINEOFFSET>{11856 + shift_px}</LINEOFFSET>")
    path = tmp_path / "dg.xml"
    path.write_text(text)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        model = dg_model(path, height_range=(0.0, 4000.0))
    found = [w for w in record if issubclass(w.category, RpbDisagreementWarning)]
    assert bool(found) == warns and model.height_range == (0.0, 4000.0)
    if warns:
        distance = float(re.search(r"differ by up to ([0-9.]+) px", str(found[0].message))[1])
        assert abs(distance - shift_px) < 2.0 and distance > RPB_DISAGREEMENT_PX


def test_text_files_name_the_rpb_file_and_the_physical_files(data_dir, tmp_path, keyword_product):
    files = keyword_product(data_dir / "stereopipeline/tests/wv_test1.xml", tmp_path / "p", "img")
    rpb = files["RPB"]
    text = rpb.read_text()
    assert "lineOffset = 10877;" in text
    rpb.write_text(text.replace("lineOffset = 10877;", "lineOffset = 11177;"))
    with pytest.warns(RpbDisagreementWarning) as record:
        model = open_model(files["IMD"])
    message = str(record[0].message)
    assert repr(str(rpb)) in message and str(files["EPH"]) in message and "px" in message
    assert model.height_range == DEFAULT_HEIGHT_RANGE
    assert open_model(rpb, model="rpc").name == "rpc"  # the RPB still opens as itself
