"""geoblock dem-info."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from geoblock.cli.main import build_cli


@pytest.fixture
def run():
    def invoke(*args):
        return CliRunner().invoke(build_cli(), list(args))

    return invoke


def test_text(run, srtm, egm96_path):
    res = run("dem-info", str(srtm), "--geoid", str(egm96_path))
    assert res.exit_code == 0, res.output
    out = res.output
    assert "SRTMHGT" in out and "EPSG:4326" in out and "geoid (SRTM" in out
    assert "egm96_15.gtx" in out and "% of the pixels" in out and "ellipsoidal" in out


def test_json(run, srtm, egm96_path):
    res = run("dem-info", str(srtm), "--geoid", str(egm96_path), "--json")
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["vertical"] == "geoid" and data["geoid"].endswith("egm96_15.gtx")
    assert data["file_height_range"] == [32.0, 2757.0]
    assert 0 < data["nodata_share"] < 0.01
    w, s, e, n = data["bounds"]
    assert w == pytest.approx(4.999583333) and n == pytest.approx(45.000416667)
    lo, hi = data["height_range"]
    assert 32.0 + 45 < lo < hi < 2757.0 + 55


def test_unstated_vertical_is_described(run, mnt_geoid):
    """A DEM that does not state its datum is described (that is when users run dem-info),
    with what to pass; heights above the ellipsoid are not made up."""
    res = run("dem-info", str(mnt_geoid))
    assert res.exit_code == 0, res.output
    assert "vertical datum:  not stated" in res.output
    assert "pass --dem-vertical geoid" in res.output and "--dem-vertical ellipsoid" in res.output
    assert "unknown above the ellipsoid" in res.output
    data = json.loads(run("dem-info", str(mnt_geoid), "--json").output)
    assert data["vertical"] is None and data["height_range"] == [None, None]
    assert data["file_height_range"][0] is not None and "--dem-vertical" in data["hint"]
    ok = run("dem-info", str(mnt_geoid), "--dem-vertical", "ellipsoid", "--json")
    assert ok.exit_code == 0 and json.loads(ok.output)["geoid"] is None
    assert json.loads(ok.output)["vertical"] == "ellipsoid"


def test_datum_hints_name_each_front_ends_option(run, mnt_geoid, tmp_path):
    """The datum error tells each user what their front end calls it: the command line's
    --dem-vertical, a block file's [dem] vertical, the Python API's vertical=."""
    from geoblock.errors import DemDatumError
    from geoblock.io.blocks import BlockDem

    import geoblock
    from geoblock.models.linescan import LinescanModel

    model = geoblock.write_model(LinescanModel.example(), tmp_path / "m.json")
    (tmp_path / "p.csv").write_text("row,col\n0,0\n")
    res = run("localize", str(model), str(tmp_path / "p.csv"), "--dem", str(mnt_geoid))
    assert res.exit_code == 1 and "pass --dem-vertical geoid" in res.output
    assert "vertical=" not in res.output
    with pytest.raises(DemDatumError, match=r'vertical = "geoid".*\[dem\] table of b\.toml'):
        BlockDem(str(mnt_geoid)).to_source("b.toml")
    with pytest.raises(DemDatumError, match="vertical='geoid'"):
        geoblock.open_dem(str(mnt_geoid))


def test_mosaic(run, srtm, mnt_geoid, egm96_path):
    res = run("dem-info", str(srtm), str(mnt_geoid), "--dem-vertical", "geoid", "--geoid",
              str(egm96_path))
    assert res.exit_code == 0, res.output
    assert "mosaic of 2 tiles" in res.output
