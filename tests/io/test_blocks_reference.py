"""The block file's [reference] table (a reference orthoimage for geoblock match): parsed,
validated naming the field, paths relative to the file, and a round trip through
write_block."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock.io import Block, BlockImage, BlockReference, read_block, write_block
from geoblock.io.blocks import BlockFileError

HEAD = """\
version = 1
method = "rpcv0"

[[images]]
id = "right"
model = "right.geom"
raster = "right.tif"
"""


def test_reference_table_is_read_relative_to_the_file(tmp_path):
    path = tmp_path / "sub" / "block.toml"
    path.parent.mkdir()
    path.write_text(HEAD + '\n[reference]\npath = "../ortho/left.tif"\naccuracy_ce90_m = 8\n'
                    "band = 2\n")
    block = read_block(path)
    assert block.reference == BlockReference((tmp_path / "ortho" / "left.tif").resolve(), 8.0, 2)
    assert isinstance(block.reference.accuracy_ce90_m, float)
    path.write_text(HEAD + '\n[reference]\npath = "left.tif"\n')
    assert read_block(path).reference == BlockReference(path.parent / "left.tif")
    path.write_text(HEAD)
    assert read_block(path).reference is None


@pytest.mark.parametrize("table, message", [
    ('accuracy_ce90_m = 8.0', "reference: the required field 'path' is missing"),
    ('path = "a.tif"\naccuracy = 8.0', r"reference: unknown field\(s\) \['accuracy'\]"),
    ('path = "a.tif"\naccuracy_ce90_m = -1.0', "'reference.accuracy_ce90_m' must be a number > 0"),
    ('path = "a.tif"\naccuracy_ce90_m = nan', "'reference.accuracy_ce90_m' must be a number > 0"),
    ('path = "a.tif"\naccuracy_ce90_m = "8 m"', "'accuracy_ce90_m' must be a integer or float"),
    ('path = "a.tif"\nband = 0', "'reference.band' must be an integer >= 1"),
    ('path = "a.tif"\nlocal_accuracy_ce90_m = -2.0',
     "'reference.local_accuracy_ce90_m' must be a number >= 0"),
    ('path = "a.tif"\nband = true', "'band' must be a integer"),
    ('path = ""', "reference.path: empty path"),
])
def test_bad_reference_tables_are_refused_naming_the_field(tmp_path, table, message):
    path = tmp_path / "block.toml"
    path.write_text(HEAD + "\n[reference]\n" + table + "\n")
    with pytest.raises(BlockFileError, match=message):
        read_block(path)


@settings(max_examples=40, deadline=None)
@given(accuracy=st.one_of(st.none(), st.floats(min_value=1e-3, max_value=1e4)),
       band=st.one_of(st.none(), st.integers(min_value=1, max_value=64)),
       local=st.one_of(st.none(), st.floats(min_value=0.0, max_value=1e4)),
       name=st.text(st.characters(whitelist_categories=("L", "N"), whitelist_characters="_-. "),
                    min_size=1, max_size=20).filter(lambda t: t.strip(" .") == t and t))
def test_reference_round_trips_through_write_block(tmp_path_factory, accuracy, band, local,
                                                  name):
    tmp = tmp_path_factory.mktemp("ref")
    block = Block((BlockImage("right", tmp / "right.geom"),), "rpcv0",
                  reference=BlockReference(tmp / "refs" / f"{name}.tif", accuracy, band, local))
    path = write_block(tmp / "block.toml", block)
    back = read_block(path)
    assert back.reference == block.reference
    assert back == block
    if accuracy is not None:
        assert math.isfinite(back.reference.accuracy_ce90_m)
