"""Every real product of the shared data opens and projects (issue 26, item 11).

Walks ``MANIFEST.md`` of the shared data: every sensor-metadata file it lists, except the
negative fixtures the manifest names in its "Negative fixtures" section, is opened with
:func:`geoblock.open_model` as a new user would (no options), and the scene's centre and four
corners are localised at the middle of the model's height range and projected back. A refusal,
a point that does not converge, or a round trip off by more than 1e-3 px fails the test. Files
that are no sensor metadata (DEMs, geoid grids, pixels, location grids, check-point arrays,
READMEs) are left out by kind, listed in :data:`NOT_SENSOR_METADATA`.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock.typing import Status

#: path fragments of the files of MANIFEST.md that hold no sensor model (by kind, not by name)
NOT_SENSOR_METADATA = (
    "/dtm/",  # DEMs and the geoid grid
    "/image/",  # pixels (crops without their RPC; the RPC is the .geom / .XML beside them)
    "/MNT_",  # DEMs
    "/GRID_",  # CNES location grids (references, not a sensor model geoblock reads)
    ".npy",  # check points
    ".geojson",  # an area of interest
    "/README",  # prose
)
MANIFEST_ROW = re.compile(r"^\| `([^`]+)` \|", re.M)


def _manifest(data_dir: Path) -> str:
    path = data_dir / "MANIFEST.md"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    return path.read_text(encoding="utf-8")


def negative_fixtures(text: str, data_dir: Path) -> set[str]:
    """The files the manifest's "Negative fixtures" section names (a reader must refuse them).

    A DigitalGlobe ``.IMD`` is negative "only where no ``.RPB`` sits beside it": with its RPB it
    is a product and opens.
    """
    section = text.split("## Negative fixtures", 1)[1].split("\n## ", 1)[0]
    names = set(re.findall(r"`([^`\s]+\.[A-Za-z]+)`", section))
    return {n for n in names
            if not (n.endswith(".IMD") and (data_dir / n).with_suffix(".RPB").is_file())}


def sensor_files(data_dir: Path) -> list[str]:
    text = _manifest(data_dir)
    negative = negative_fixtures(text, data_dir)
    return [name for name in MANIFEST_ROW.findall(text)
            if not name.endswith("/") and name not in negative
            and not any(k in "/" + name for k in NOT_SENSOR_METADATA)]


def test_the_manifest_walk_finds_the_sensor_files_and_skips_the_negative_ones(data_dir):
    text = _manifest(data_dir)
    negative = negative_fixtures(text, data_dir)
    files = sensor_files(data_dir)
    assert {"shareloc/rpc/fake_rpc.txt", "stereopipeline/tests/spot_example1.xml"} <= negative
    assert not negative & set(files)
    assert {"cosicorr3d/test_dataset/WV1.XML", "rpcm/test_rpc_files/rpc_WV1.xml"} <= set(files)
    assert "gdal-autotest/gcore/data/md_dg.IMD" in files  # its .RPB sits beside it
    assert len(files) >= 45, files


def pytest_generate_tests(metafunc):
    if "manifest_file" in metafunc.fixturenames:
        from .conftest import DATA_DIR  # the folder of the data_dir fixture

        names = sensor_files(DATA_DIR) if (DATA_DIR / "MANIFEST.md").is_file() else []
        metafunc.parametrize("manifest_file", names or ["<no MANIFEST.md>"])


def test_every_real_product_opens_and_projects(manifest_file, data_dir):
    path = data_dir / manifest_file
    if not path.is_file():
        pytest.skip(f"{manifest_file} is listed in MANIFEST.md but absent from {data_dir}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # warnings are not refusals (e.g. an RPB that disagrees)
        model = geoblock.open_model(path)
    rows, cols = model.shape
    row = np.array([(rows - 1) / 2.0, 0.0, 0.0, rows - 1.0, rows - 1.0])
    col = np.array([(cols - 1) / 2.0, 0.0, cols - 1.0, 0.0, cols - 1.0])
    h = float(np.mean(model.height_range))
    ground, status = model.backproject_with_status(row, col, np.full(5, h))
    names = [Status(int(s)).name for s in status]
    assert np.all(status == Status.CONVERGED), f"{manifest_file}: localised with {names}"
    image, status = model.project_with_status(ground.lon, ground.lat, ground.h)
    names = [Status(int(s)).name for s in status]
    assert np.all(status == Status.CONVERGED), f"{manifest_file}: projected with {names}"
    assert np.max(np.hypot(image.row - row, image.col - col)) < 1e-3
