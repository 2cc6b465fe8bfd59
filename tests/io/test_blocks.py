"""Block files: read/write round trip, validation errors naming the field, and the TOML writer."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock import errors
from geoblock.errors import GeoblockIOError
from geoblock.io import Block, BlockDem, BlockImage, read_block, write_block
from geoblock.io.blocks import BlockFileError, dumps_toml

EXAMPLE = """\
version = 1
name = "three strips"
method = "mba"

[points]
ground = "ground.csv"
image = "pts/image.csv"
truth = "/abs/truth.csv"

[dem]
path = "dem.tif"
vertical = "geoid"
geoid = "../grids/egm96_15.gtx"

[options]
dem_control = true
max_iterations = 20
tolerance = 1e-6
weights = [1.0, 2.5]
[options.collocation]
filter_ratio = 0.2

[outputs]
directory = "out"

[[images]]
id = "strip1"
model = "strip1.json"
raster = "strip1.tif"
parameters = "dg"
sigmas = { dp_along = 10.0, roll_bias = 1e-5 }

[[images]]
id = "strip2"
model = "models/strip2.json"
"""


def test_read_example_resolves_paths_relative_to_the_file(tmp_path):
    path = tmp_path / "block.toml"
    path.write_text(EXAMPLE)
    block = read_block(path)
    assert block.name == "three strips" and block.method == "mba"
    assert [im.id for im in block.images] == ["strip1", "strip2"]
    assert block.images[0].model == tmp_path / "strip1.json"
    assert block.images[0].raster == tmp_path / "strip1.tif"
    assert block.images[0].parameters == "dg"
    assert dict(block.images[0].sigmas) == {"dp_along": 10.0, "roll_bias": 1e-5}
    assert block.images[1].raster is None and block.images[1].parameters is None
    assert block.image_points == tmp_path / "pts" / "image.csv"
    assert block.truth == Path("/abs/truth.csv")
    assert block.dem == BlockDem(str(tmp_path / "dem.tif"), "geoid",
                                 (tmp_path / ".." / "grids" / "egm96_15.gtx").resolve())
    assert block.options["dem_control"] is True and block.options["weights"] == (1.0, 2.5)
    assert block.options["collocation"]["filter_ratio"] == 0.2
    assert block.outputs["directory"] == tmp_path / "out"
    with pytest.raises(TypeError):
        block.options["x"] = 1  # read-only
    assert block.image("strip2").model == tmp_path / "models" / "strip2.json"


def test_write_read_round_trip_and_relative_paths(tmp_path):
    src = tmp_path / "a" / "block.toml"
    src.parent.mkdir()
    src.write_text(EXAMPLE)
    block = read_block(src)
    out = tmp_path / "b" / "copy.toml"
    out.parent.mkdir()
    assert write_block(out, block) == out
    assert read_block(out) == block
    text = out.read_text()
    assert 'model = "../a/strip1.json"' in text  # relative to the new file
    assert 'path = "../a/dem.tif"' in text
    assert list(out.parent.iterdir()) == [out]  # no temporary file left
    # the written file is plain TOML
    assert tomllib.loads(text)["images"][0]["sigmas"] == {"dp_along": 10.0, "roll_bias": 1e-5}


def test_constant_dem_and_minimal_block(tmp_path):
    block = Block((BlockImage("a", tmp_path / "a.json"),), "rpcv0", dem=BlockDem("const:250"))
    path = write_block(tmp_path / "min.toml", block)
    back = read_block(path)
    assert back == block and back.dem.source == "const:250"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("method = 'mba'\n", r"required field 'images' is missing"),
        ("[[images]]\nid = 'a'\nmodel = 'a.json'\n", r"required field 'method' is missing"),
        ("method = 'mba'\n[[images]]\nmodel = 'a.json'\n", r"images\[0\]: the required field 'id'"),
        ("method = 'mba'\n[[images]]\nid = 'a'\nmodel = 3\n", r"'model' must be a string, got 3"),
        ("method = 'mba'\n[[images]]\nid = 'a'\nmodel = 'a'\nbogus = 1\n",
         r"images\[0\]: unknown field\(s\) \['bogus'\]"),
        ("method = 'mba'\n[[images]]\nid = 'a'\nmodel = 'a'\n[[images]]\nid = 'a'\nmodel = 'b'\n",
         r"'images\[1\]\.id': duplicate image id 'a'"),
        ("method = 'MBA!'\n[[images]]\nid = 'a'\nmodel = 'a'\n", r"'method' must be a lower-case"),
        ('method = "mba\\n"\n[[images]]\nid = "a"\nmodel = "a"\n',
         r"'method' must be a lower-case"),
        ("version = 2\nmethod = 'mba'\n", r"'version' 2 is not supported"),
        ("method = 'mba'\n[dem]\nvertical = 'geoid'\n[[images]]\nid = 'a'\nmodel = 'a'\n",
         r"dem: the required field 'path' is missing"),
        ("method = 'mba'\n[dem]\npath = 'd.tif'\nvertical = 'egm'\n[[images]]\nid = 'a'\n"
         "model = 'a'\n", r"'dem.vertical' must be 'ellipsoid' or 'geoid'"),
        ("method = 'mba'\n[[images]]\nid = 'a'\nmodel = 'a'\nsigmas = { roll = 'x' }\n",
         r"'sigmas.roll' must be a number"),
        ("method = 'mba'\n[points]\nground = true\n[[images]]\nid = 'a'\nmodel = 'a'\n",
         r"points: 'ground' must be a string, got True"),
        ("method = 'mba'\nextra = 1\n[[images]]\nid = 'a'\nmodel = 'a'\n",
         r"unknown field\(s\) \['extra'\]"),
        ("method = 'mba\n", r"not a valid TOML file"),
        ("method = 'dg'\n[[images]]\nid = 'a'\nmodel = 'a'\nparameter_options = { k = [1] }\n",
         r"'parameter_options.k' must be a number, a string or a boolean"),
    ],
)
def test_invalid_block_files_name_the_field(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(BlockFileError, match=message) as info:
        read_block(path)
    assert str(path) in str(info.value)


def test_block_and_point_file_errors_are_input_file_errors_not_model_errors():
    from geoblock.io import blocks, points

    assert blocks.BlockFileError is errors.BlockFileError  # the old import path still works
    assert points.PointFileError is errors.PointFileError
    for cls in (errors.BlockFileError, errors.PointFileError, errors.ModelFormatError):
        assert issubclass(cls, errors.InputFileError)
        assert issubclass(cls, ValueError) and issubclass(cls, errors.GeoblockError)
    for cls in (errors.BlockFileError, errors.PointFileError):
        assert not issubclass(cls, errors.ModelFormatError)  # a block or point file is no model


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(GeoblockIOError, match="cannot read block file"):
        read_block(tmp_path / "nope.toml")
    block = Block((BlockImage("a", tmp_path / "a.json"),), "mba")
    with pytest.raises(GeoblockIOError, match="does not exist"):
        write_block(tmp_path / "no" / "b.toml", block)


# ---------------------------------------------------------------------------- the TOML writer
keys = st.text(min_size=1, max_size=12)
scalars = (st.text(max_size=20) | st.booleans() | st.integers(-(2**63), 2**63 - 1)
           | st.floats(allow_nan=False))
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(keys, inner, max_size=4), max_leaves=12)
documents = st.dictionaries(keys, values | st.lists(st.dictionaries(keys, values, max_size=3),
                                                    min_size=1, max_size=3), max_size=6)


@settings(max_examples=200, deadline=None)
@given(documents)
def test_dumps_toml_round_trips_through_tomllib(doc):
    assert tomllib.loads(dumps_toml(doc)) == doc


def test_written_block_file_reads_top_down(tmp_path):
    """The layout a user edits: the block's own keys, then one section per table, the images
    last as [[images]] sections (their sigmas a sub-table); a table appended after the keys
    (here [options], by a text edit) does not swallow anything."""
    block = Block(
        (BlockImage("strip1", tmp_path / "strip1.json", tmp_path / "strip1.tif"),
         BlockImage("strip2", tmp_path / "m" / "strip2.json", parameters="dg",
                    sigmas={"roll_bias": 1e-5})),
        "dg", tmp_path / "ground.csv", tmp_path / "image.csv", dem=BlockDem("const:250", sigma=5.0),
        outputs={"directory": tmp_path / "out"}, name="two strips",
    )
    path = write_block(tmp_path / "block.toml", block)
    assert path.read_text() == """\
# geoblock block file (docs: user-guide/simulation.md)
version = 1
name = "two strips"
method = "dg"

[points]
ground = "ground.csv"
image = "image.csv"

[dem]
path = "const:250"
sigma = 5.0

[outputs]
directory = "out"

[[images]]
id = "strip1"
model = "strip1.json"
raster = "strip1.tif"

[[images]]
id = "strip2"
model = "m/strip2.json"
parameters = "dg"

[images.sigmas]
roll_bias = 1e-05
"""
    edited = 'method = "dg"\n[options]\nrobust = "huber"\n'
    path.write_text(path.read_text().replace('method = "dg"\n', edited))
    assert read_block(path).options == {"robust": "huber"}
    assert [im.id for im in read_block(path).images] == ["strip1", "strip2"]


def test_dumps_toml_refuses_what_toml_cannot_hold():
    with pytest.raises(BlockFileError, match=r"images\.0\.raster: cannot write a complex"):
        dumps_toml({"images": [{"raster": 1j}]})
    assert tomllib.loads(dumps_toml({"p": Path("a/b"), "t": (1, 2), "np": np.float64(0.25)})) == {
        "p": "a/b", "t": [1, 2], "np": 0.25}


def test_dumps_toml_non_finite_floats():
    back = tomllib.loads(dumps_toml({"a": math.inf, "b": -math.inf, "c": math.nan, "d": 1e300}))
    assert back["a"] == math.inf and back["b"] == -math.inf and math.isnan(back["c"])
    assert back["d"] == 1e300


def test_block_file_options_are_the_engines_keywords():
    """[options] keys are adjust()'s keywords (sigma_px aside, a reading option): the table
    cannot drift from the engine's signature."""
    import inspect

    from geoblock.adjust import adjust
    from geoblock.io.blocks import ADJUST_OPTIONS

    keywords = set(inspect.signature(adjust).parameters) - {"block", "progress", "mode"}
    assert set(ADJUST_OPTIONS) - {"sigma_px"} == keywords


def test_dumps_toml_keeps_arrays_of_values_on_one_line():
    """Scenario and block files stay as short to read as before tomli-w (which alone spreads
    every array over several lines); a table inside an array of values is an inline table."""
    text = dumps_toml({"relief": [150.0, 1100.0], "m": [[1, 2], [3]], "mix": [1, {"q": [1]}],
                       "t": {"b c": [True]}})
    assert text == ('relief = [150.0, 1100.0]\nm = [[1, 2], [3]]\nmix = [1, {q = [1]}]\n\n'
                    '[t]\n"b c" = [true]\n')
    assert tomllib.loads(text)["mix"] == [1, {"q": [1]}]


def test_parameter_options_reach_the_parameter_set(tmp_path):
    """``parameter_options`` of an image go to its model's ``with_parameter_set``: the jitter
    set's knot spacing from the block file; an option the set does not know names the image."""
    from geoblock.io import open_block, write_model
    from geoblock.models.linescan import LinescanModel

    model = LinescanModel.example((600, 200)).replace(location_accuracy_m=10.0)
    write_model(model, tmp_path / "a.json")
    (tmp_path / "image.csv").write_text("id,image,row,col\np1,a,10.0,20.0\n")
    text = ("method = 'dg'\n[points]\nimage = 'image.csv'\n[[images]]\nid = 'a'\n"
            "model = 'a.json'\nparameters = 'jitter'\nparameter_options = { knot_lines = 50 }\n")
    path = tmp_path / "block.toml"
    path.write_text(text)
    spec = read_block(path)
    assert dict(spec.images[0].parameter_options) == {"knot_lines": 50}
    assert read_block(write_block(tmp_path / "again.toml", spec)) == spec
    opened = open_block(path)
    jittered = opened.block.models["a"]
    default = model.with_parameter_set("jitter")
    assert jittered.jitter.interval_s == pytest.approx(
        50 * model.line_times.period_magnitude_s)
    assert jittered.jitter.interval_s != default.jitter.interval_s
    path.write_text(text.replace("knot_lines = 50", "knot_spacing = 50"))
    with pytest.raises(BlockFileError, match=r"images\[0\] \(a\).*knot_spacing"):
        open_block(path)
