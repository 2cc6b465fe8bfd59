"""``geoblock match``: help, and one clear line for each misuse."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import geoblock
from geoblock.cli.main import build_cli
from geoblock.testing.synthetic import AffineCamera


@pytest.fixture
def invoke():
    cli = build_cli()

    def run(*args):
        return CliRunner().invoke(cli, ["match", *map(str, args)])

    return run


@pytest.fixture
def files(tmp_path):
    model = AffineCamera.example()
    image = tmp_path / "scene.tif"
    geoblock.io.write_image(image, np.ones(model.shape, np.uint8))
    return {"image": image, "model": geoblock.write_model(model, tmp_path / "scene.json")}


def test_help_shows_both_forms_and_examples(invoke):
    result = invoke("--help")
    assert result.exit_code == 0
    assert "IMAGE IMAGE... | BLOCK.toml" in result.output
    assert "Examples:" in result.output and "--diagnostics" in result.output


def test_usage_errors(invoke, files):
    img, model = files["image"], files["model"]
    result = invoke(img, img, "--model", model, "--model", model)
    assert result.exit_code == 2 and "--dem DEM is required" in result.output
    result = invoke(img, "--dem", "const:0")
    assert result.exit_code == 2 and "two or more IMAGEs" in result.output
    result = invoke(img, img, "--model", model, "--dem", "const:0")
    assert result.exit_code == 2 and "--model once per IMAGE" in result.output
    result = invoke(img, img, "--image-id", "x", "--dem", "const:0")
    assert result.exit_code == 2 and "--image-id once per IMAGE" in result.output
    result = invoke("block.toml", "--model", model)
    assert result.exit_code == 2 and "not to a block file" in result.output
    result = invoke(img, img, "--ratio", "1.5", "--dem", "const:0")
    assert result.exit_code == 2 and "--ratio" in result.output


def test_errors_are_one_line_naming_the_file(invoke, files, tmp_path):
    img, model = files["image"], files["model"]
    # the same image twice gets the same default id
    result = invoke(img, img, "--model", model, "--model", model, "--dem", "const:0")
    assert result.exit_code == 1
    assert "Error: duplicate image id(s) ['scene']" in result.output
    # a flat image: no keypoint where the two overlap
    result = invoke(img, img, "--model", model, "--model", model, "--image-id", "a", "--image-id", "b",
                    "--dem", "const:0")
    assert result.exit_code == 1
    assert f"Error: {img}: no SIFT keypoint" in result.output
    block = tmp_path / "block.toml"
    block.write_text(f'method = "default"\n[[images]]\nid = "a"\nmodel = "{model}"\n'
                     f'[[images]]\nid = "b"\nmodel = "{model}"\nraster = "{img}"\n')
    result = invoke(block)
    assert result.exit_code == 1
    assert "images[0] (a) name(s) no 'raster'" in result.output
    result = invoke(tmp_path / "missing.tif", img, "--dem", "const:0")
    assert result.exit_code == 1 and "missing.tif" in result.output
