"""Fixtures of the command-line tests: a click runner, a model JSON and point files."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

import geoblock
from geoblock.cli.main import build_cli
from geoblock.testing.synthetic import AffineCamera


@pytest.fixture
def runner() -> CliRunner:
    return CliRunner()


@pytest.fixture
def cli():
    """The geoblock group over the process-wide plugin manager (as the console script)."""
    return build_cli()


@pytest.fixture(scope="session")
def affine():
    return AffineCamera.example()


@pytest.fixture
def model_path(tmp_path, affine):
    """geoblock model JSON of AffineCamera.example()."""
    return str(geoblock.write_model(affine, tmp_path / "affine.json"))
