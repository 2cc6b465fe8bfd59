"""Fixtures of the geoblock-spot tests (self-contained: the tests run with --import-mode=importlib).

Real data lives in ``<repo>/../shared/data``; ``GEOBLOCK_TEST_DATA`` overrides it. Tests that
need it skip with the reason when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The shared real-data folder (skips the test when it is absent)."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real test data not found at {DATA_DIR} (set GEOBLOCK_TEST_DATA)")
    return DATA_DIR
