"""The metadata-field readers name the file and the field for every kind of bad value."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from geoblock.errors import GeoblockIOError, MetadataFieldError, ModelFormatError
from geoblock.io.metadata import Fields, read_xml

XML = """<Doc><Size><NROWS>12</NROWS><NCOLS>12.5</NCOLS></Size>
<V>1 2 3</V><E/><Bad>abc</Bad><Inf>inf</Inf><P><X>1</X></P><P><X>2</X></P></Doc>"""


@pytest.fixture
def doc(tmp_path):
    path = tmp_path / "meta.xml"
    path.write_text(XML)
    return read_xml(path)


def test_xml_fields_read_good_values(doc):
    assert doc.integer("Size/NROWS", minimum=1) == 12
    assert doc.number("Size/NCOLS") == 12.5
    assert doc.numbers("V", count=3).tolist() == [1.0, 2.0, 3.0]
    assert [doc.number("X", p, "P/") for p in doc.nodes("P", minimum=2)] == [1.0, 2.0]
    assert doc.optional_text("E") is None and doc.optional_text("Nope") is None


@pytest.mark.parametrize(
    ("call", "field", "problem"),
    [
        (lambda d: d.text("Nope"), "Nope", "missing"),
        (lambda d: d.text("E"), "E", "empty"),
        (lambda d: d.number("Bad"), "Bad", "not a number"),
        (lambda d: d.number("Inf"), "Inf", "not finite"),
        (lambda d: d.integer("Size/NCOLS"), "Size/NCOLS", "whole number"),
        (lambda d: d.integer("Size/NROWS", maximum=10), "Size/NROWS", "outside"),
        (lambda d: d.numbers("V", count=2), "V", "expected 2 numbers"),
        (lambda d: d.nodes("P", minimum=3), "P", "at least 3"),
        (lambda d: d.number("X", d.nodes("P")[0], "P/", low=5), "P/X", "outside"),
    ],
)
def test_xml_field_errors_name_file_and_field(doc, call, field, problem):
    with pytest.raises(MetadataFieldError, match=problem) as info:
        call(doc)
    assert info.value.field == field and info.value.source.endswith("meta.xml")
    assert str(info.value).startswith(info.value.source)


def test_unreadable_and_truncated_xml(tmp_path):
    with pytest.raises(GeoblockIOError, match="nothing.xml"):
        read_xml(tmp_path / "nothing.xml")
    bad = tmp_path / "cut.xml"
    bad.write_text(XML[:40])
    with pytest.raises(ModelFormatError, match=r"cut.xml: XML: not well-formed"):
        read_xml(bad)


def test_plugins_raise_their_own_error_class(tmp_path):
    class MyFormatError(ModelFormatError):
        def __init__(self, source, field, problem):
            super().__init__(f"{source} [{field}] {problem}")

    path = tmp_path / "m.xml"
    path.write_text(XML)
    with pytest.raises(MyFormatError, match=r"\[Bad\] 'abc' is not a number"):
        read_xml(path, MyFormatError).number("Bad")


def test_mapping_fields():
    f = Fields("scene.toml", {"n": 3, "x": 1.5, "s": "a", "b": True, "t": {"k": [1, 2]},
                              "rows": [{"v": 1}, {"v": "no"}]})
    assert f.number("n", integer=True) == 3 and f.number("x", low=0) == 1.5
    assert f.string("s", choices=["a", "b"]) == "a" and f.boolean("b") is True
    assert f.table("t").pair("k", integer=True) == (1, 2)
    assert f.number("absent", None) is None and f.table("absent").data == {}
    with pytest.raises(MetadataFieldError, match=r"scene.toml: t.k: high must be >= low"):
        Fields("scene.toml", {"t": {"k": [2, 1]}}).table("t").pair("k")
    with pytest.raises(MetadataFieldError, match=r"rows\[1\].v: must be a number"):
        [r.number("v") for r in f.tables("rows")]
    with pytest.raises(MetadataFieldError, match=r"b: must be a number, got a boolean"):
        f.number("b")
    with pytest.raises(MetadataFieldError, match=r"absent: required key missing"):
        f.string("absent")
    with pytest.raises(MetadataFieldError, match=r"unknown key; allowed: n, x"):
        f.known(["n", "x"])
    with pytest.raises(MetadataFieldError, match=r"s: must be one of b"):
        f.string("s", choices=["b"])


@given(st.one_of(st.text(max_size=8), st.floats(), st.integers(), st.booleans(), st.none()))
def test_mapping_number_never_escapes_with_anything_but_a_field_error(value):
    f = Fields("f.toml", {"k": value})
    try:
        out = f.number("k", low=0.0)
    except MetadataFieldError as exc:
        assert exc.field == "k"
    else:
        assert np.isfinite(out) and out >= 0.0
