"""COSI-Corr3D's test assertions whose data is in shared/data, re-expressed against geoblock's
public API.

Source: https://github.com/SaifAati/Geospatial-COSICorr3D at commit
2296a3134e7a527357623604e5a22cbf39820768 (``../shared/data/MANIFEST.md``). Only
``tests/test_geoRSM.py`` l.17-34 (``test_rsm_generation``) has its inputs here: every other test
needs images, DEMs or the expected JSON (``expec_test_georsm.json``) absent from the snapshot,
and ``WV2.XML`` / ``WV3.XML`` are not in shared/data either.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import geoblock

SRC = "SaifAati/Geospatial-COSICorr3D@2296a3134e7a tests/test_geoRSM.py"


@pytest.fixture(scope="module")
def ds(data_dir) -> Path:
    return data_dir / "cosicorr3d/test_dataset"


def _check_physical(model):
    """A physical pushbroom model that works: its scene centre backprojects and projects back
    (1e-6 px), so 'built' means usable."""
    rows, cols = model.shape
    lo, hi = model.height_range
    h = float(np.clip(0.0, lo, hi))
    g = model.backproject((rows - 1) / 2, (cols - 1) / 2, h)
    ic = model.project(g.lon, g.lat, h)
    assert abs(ic.row - (rows - 1) / 2) < 1e-6 and abs(ic.col - (cols - 1) / 2) < 1e-6


@pytest.mark.parametrize("name", ["SPOT1.DIM", "SPOT2.DIM", "SPOT3.DIM", "SPOT4.DIM", "SPOT5.DIM",
                                  "SPOT6.XML"])
def test_rsm_generation_spot(ds, name):
    """tests/test_geoRSM.py l.18-34 (test_rsm_generation): COSI-Corr3D builds its rigorous
    sensor model (cSpot15 for SPOT 1-5, cSpot67 for SPOT 6) from each file. geoblock: the file
    opens as a physical line-scan model (not an RPC), which backprojects and projects back."""
    model = geoblock.open_model(ds / name)
    assert model.name not in ("rpc", "rfm")
    _check_physical(model)


def test_rsm_generation_wv1_reverse_scan(ds):
    """tests/test_geoRSM.py l.18-34 (test_rsm_generation): COSI-Corr3D builds its cDigitalGlobe
    model from WV1.XML, a reverse-scanned product (SCANDIRECTION Reverse). geoblock: the
    DigitalGlobe rigorous model opens and works."""
    model = geoblock.open_model(ds / "WV1.XML")
    assert model.name == "dg-rigorous"
    _check_physical(model)
