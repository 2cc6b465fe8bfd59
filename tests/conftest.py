"""Shared fixtures. Real data lives in ../shared/data (override with GEOBLOCK_TEST_DATA)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import geoblock.testing
from geoblock.plugins import PLUGIN_MODULES_VARIABLE
from geoblock.testing.plugin import MODULE as SYNTHETIC_MODELS
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

REPO = Path(__file__).resolve().parents[1]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))


def enable_synthetic_models_everywhere() -> None:
    """The synthetic test models are opt-in (they are not user models). geoblock's own tests
    use them in this process and in the processes they start (the ``geoblock`` command), so
    both get them: the Python switch here, the environment variable for subprocesses."""
    geoblock.testing.enable_synthetic_models()
    named = [m.strip() for m in os.environ.get(PLUGIN_MODULES_VARIABLE, "").split(",")]
    if SYNTHETIC_MODELS not in named:
        os.environ[PLUGIN_MODULES_VARIABLE] = ",".join([*filter(None, named), SYNTHETIC_MODELS])


enable_synthetic_models_everywhere()


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
