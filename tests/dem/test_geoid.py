"""The EGM96 geoid: shareloc's values (test_dtm_intersection.py l.42-68) and file discovery."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

import geoblock

from geoblock.dem import geoid as geoid_mod
from geoblock.dem.geoid import Geoid, find_geoid
from geoblock.errors import DemError, GeoblockError


@pytest.fixture(scope="module")
def egm96(data_dir) -> Geoid:
    return Geoid(data_dir / "shareloc" / "dtm" / "geoid" / "egm96_15.gtx")


@pytest.mark.parametrize(
    ("lon", "lat", "expected"),
    [
        (0.1, 0.0, 17.12881622),
        (0.0, 0.0, 17.16157913),
        (10.125, 0.0, 8.72032166),
        (5.19368066, 44.20749145, 50.8618354),
        (5.17381589, 44.22559175, 50.87610),
        (-119.0, -9, -12.516327),
        (179.875, 44.0, -7.975677),
        (np.nan, np.nan, np.nan),
    ],
)
def test_shareloc_geoid_values(egm96, lon, lat, expected):
    assert float(egm96.undulation(lon, lat)) == pytest.approx(expected, abs=1e-6, nan_ok=True)


def test_longitude_wrap_and_shapes(egm96):
    lon = np.array([[179.9, -180.1], [540.0, 0.0]])
    n = egm96.undulation(lon, 10.0)
    assert n.shape == (2, 2)
    assert n[0, 1] == pytest.approx(float(egm96.undulation(179.9, 10.0)), abs=1e-12)
    assert n[1, 0] == pytest.approx(float(egm96.undulation(180.0, 10.0)), abs=1e-12)
    assert n[1, 0] == pytest.approx(float(egm96.undulation(-180.0, 10.0)), abs=1e-12)
    assert np.isfinite(egm96.undulation([0.0, 0.0], [90.0, -90.0])).all()


def test_undulation_range_bounds_values(egm96):
    lo, hi = egm96.undulation_range((5.0, 44.0, 6.0, 45.0))
    rng = np.random.default_rng(0)
    n = egm96.undulation(rng.uniform(5, 6, 1000), rng.uniform(44, 45, 1000))
    assert lo <= n.min() and n.max() <= hi


def test_pickles_by_path(egm96):
    data = pickle.dumps(egm96)
    assert len(data) < 500
    assert pickle.loads(data) == egm96


def test_find_explicit_and_env(egm96, monkeypatch):
    assert find_geoid(egm96.path) == egm96
    assert find_geoid(egm96) is egm96
    monkeypatch.setenv("GEOBLOCK_GEOID", egm96.path)
    assert find_geoid() == egm96
    monkeypatch.setenv("GEOBLOCK_GEOID", "/nonexistent/egm96_15.gtx")
    with pytest.raises(DemError, match="GEOBLOCK_GEOID"):
        find_geoid()


def test_not_found_message_lists_places(monkeypatch, tmp_path):
    monkeypatch.delenv("GEOBLOCK_GEOID", raising=False)
    monkeypatch.setattr(geoid_mod, "geoid_search_path", lambda: [tmp_path / "a", tmp_path / "b"])
    with pytest.raises(GeoblockError) as info:
        find_geoid()
    text = str(info.value)
    assert "apt-get install proj-data" in text and "GEOBLOCK_GEOID" in text and "geoid=" in text
    assert str(tmp_path / "a") in text and str(tmp_path / "b") in text


def test_search_path_includes_standard_dirs():
    dirs = geoid_mod.geoid_search_path()
    assert Path("/usr/share/proj") in dirs


def test_found_in_proj_data_dir_when_installed(monkeypatch):
    if not Path("/usr/share/proj/egm96_15.gtx").is_file():
        pytest.skip("proj-data not installed (apt-get install proj-data)")
    monkeypatch.delenv("GEOBLOCK_GEOID", raising=False)
    assert find_geoid().name == "egm96_15.gtx"


def test_bad_file(tmp_path):
    bad = tmp_path / "bad.gtx"
    bad.write_bytes(b"not a grid")
    with pytest.raises(DemError, match="bad.gtx"):
        Geoid(bad)


def test_not_found_hint_names_each_front_ends_setting(monkeypatch, tmp_path):
    """The command line says --geoid, a block file its [dem] geoid key (issue 25, item 5)."""
    from click.testing import CliRunner

    from geoblock.cli.main import build_cli
    from geoblock.errors import GeoidNotFoundError
    from geoblock.io.blocks import BlockDem

    monkeypatch.delenv("GEOBLOCK_GEOID", raising=False)
    monkeypatch.setattr(geoid_mod, "geoid_search_path", lambda: [tmp_path / "nowhere"])
    dem = tmp_path / "dem.tif"
    with rasterio.open(dem, "w", driver="GTiff", width=4, height=4, count=1, dtype="float32",
                       crs="EPSG:4326", transform=Affine(0.01, 0, 5, 0, -0.01, 44)) as ds:
        ds.write(np.zeros((1, 4, 4), np.float32))
    result = CliRunner().invoke(build_cli(), ["dem-info", str(dem), "--dem-vertical", "geoid"])
    assert result.exit_code == 1 and "pass --geoid GTX" in result.output
    assert "geoid=" not in result.output
    with pytest.raises(GeoidNotFoundError, match=r'geoid = "path/to/egm96_15.gtx" in the \[dem\]'):
        BlockDem(str(dem), vertical="geoid").to_source("b.toml")
    with pytest.raises(GeoidNotFoundError, match="pass geoid="):
        geoblock.open_dem(str(dem), vertical="geoid")
