"""Shared fixtures. Real data lives in ../shared/data (override with GEOBLOCK_TEST_DATA)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The shared real-data folder; tests that need it skip with a reason when it is absent."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real test data not found at {DATA_DIR} (set GEOBLOCK_TEST_DATA)")
    return DATA_DIR


@pytest.fixture(scope="session")
def affine_camera() -> AffineCamera:
    return AffineCamera.example()


@pytest.fixture(scope="session")
def pushbroom() -> ConstantVelocityPushbroom:
    return ConstantVelocityPushbroom.example(roll=0.01)


@pytest.fixture(params=["affine", "pushbroom"])
def synthetic_model(request, affine_camera, pushbroom):
    """Each synthetic model: one implements ground->image, the other image->ground."""
    return {"affine": affine_camera, "pushbroom": pushbroom}[request.param]


def pytest_sessionstart(session):
    """In CI (CI=true) the shared data must be present: skipped real-data tests prove nothing."""
    if os.environ.get("CI", "").lower() in ("true", "1") and not DATA_DIR.is_dir():
        raise pytest.UsageError(
            f"CI=true but the real test data is missing at {DATA_DIR}; CI clones shared/ beside "
            "the repository (or set GEOBLOCK_TEST_DATA)"
        )
