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


def test_unstated_vertical_error(run, mnt_geoid):
    res = run("dem-info", str(mnt_geoid))
    assert res.exit_code == 1
    assert "Error:" in res.output and "vertical" in res.output
    ok = run("dem-info", str(mnt_geoid), "--vertical", "ellipsoid", "--json")
    assert ok.exit_code == 0 and json.loads(ok.output)["geoid"] is None


def test_mosaic(run, srtm, mnt_geoid, egm96_path):
    res = run("dem-info", str(srtm), str(mnt_geoid), "--vertical", "geoid", "--geoid",
              str(egm96_path))
    assert res.exit_code == 0, res.output
    assert "mosaic of 2 tiles" in res.output
