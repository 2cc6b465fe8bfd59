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


# ------------------------------------------------------------------ raw content for readers
def test_read_bytes_whole_or_a_range_and_decode_text(tmp_path):
    from geoblock.io.metadata import decode_text, read_bytes

    path = tmp_path / "head.bin"
    path.write_bytes(b"0123456789")
    assert read_bytes(path) == b"0123456789"
    assert read_bytes(path, 4) == b"0123" and read_bytes(path, 3, offset=5) == b"567"
    assert read_bytes(path, 8, offset=6) == b"6789"  # fewer at the end
    with pytest.raises(GeoblockIOError, match="nothing.bin"):
        read_bytes(tmp_path / "nothing.bin", 16)
    with pytest.raises(GeoblockIOError, match=str(tmp_path.name)):
        read_bytes(tmp_path)  # a directory
    assert decode_text("\ufeffLINE_OFF: 1".encode()) == "LINE_OFF: 1"  # BOM dropped
    assert decode_text(b"caf\xe9") == "caf\u00e9"  # not UTF-8: Latin-1
    assert decode_text(b"\xff", encodings=("ascii",)) == ""


def test_read_xml_unknown_encoding_and_namespaces(tmp_path):
    bad = tmp_path / "enc.xml"
    bad.write_text('<?xml version="1.0" encoding="UTFabc"?><a/>')
    with pytest.raises(MetadataFieldError, match=r"enc.xml: XML: not well-formed.*UTFabc"):
        read_xml(bad)
    ns = tmp_path / "ns.xml"
    ns.write_text('<r xmlns="http://x"><A><B>2</B></A></r>')
    assert read_xml(ns).find("A/B") is None
    assert read_xml(ns, strip_namespaces=True).number("A/B") == 2.0


def test_an_element_s_own_text_is_named_by_its_label(doc):
    v = doc.node("V")
    assert doc.numbers(".", v, "Doc/V/").tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(MetadataFieldError) as info:
        doc.number(".", doc.node("Bad"), "Doc/Bad/")
    assert info.value.field == "Doc/Bad"


TIMES = """<T><A>2005-03-13T05:21:07.332158Z</A><B>2018-12-26T10:39:38.1234567</B>
<C>1750-01-01T00:00:00</C><D>yesterday</D><E>NaT</E><F>2005-13-40T00:00:00</F></T>"""


def test_xml_times(tmp_path):
    path = tmp_path / "t.xml"
    path.write_text(TIMES)
    doc = read_xml(path)
    a = doc.time("A")
    assert a == np.datetime64("2005-03-13T05:21:07.332158", "us") and a.dtype == "M8[us]"
    b = doc.time("B", unit="ns")
    assert b == np.datetime64("2018-12-26T10:39:38.123456700", "ns")
    assert doc.time("B") == np.datetime64("2018-12-26T10:39:38.123456", "us")
    assert doc.time("C") == np.datetime64("1750-01-01", "us")  # no years: any year
    for where, problem in [("C", "plausible"), ("D", "ISO-8601"), ("E", "ISO-8601"),
                           ("F", "ISO-8601")]:
        with pytest.raises(MetadataFieldError, match=problem) as info:
            doc.time(where, years=(1950, 2200))
        assert info.value.field == where


def test_sample_checks_name_the_field_and_the_sample(doc):
    doc.bounded([0.1, -0.2], 0.5, "Att/YAW", "angle (rad)")
    with pytest.raises(MetadataFieldError, match=r"angle \(rad\) -0.7 \(sample 2\)") as info:
        doc.bounded([0.1, -0.7, np.nan], 0.5, "Att/YAW", "angle (rad)")
    assert info.value.field == "Att/YAW"
    with pytest.raises(MetadataFieldError, match=r"\(sample 3\)"):
        doc.bounded([0.1, 0.2, np.nan], 0.5, "Att/YAW", "angle (rad)")
    doc.increasing([1.0, 2.0, 3.0], "Points/TIME")
    doc.increasing([5.0], "Points/TIME")
    with pytest.raises(MetadataFieldError, match=r"times are not strictly increasing \(sample 3 "
                                                 r"of 4 is not after sample 2\)"):
        doc.increasing([1.0, 2.0, 2.0, 1.0], "Points/TIME", "times")
    f = Fields("s.toml", {}, where="table.")
    with pytest.raises(MetadataFieldError, match=r"s.toml: table.t: values are not strictly"):
        f.increasing([0.0, -1.0], "t")


def test_mapping_numbers_from_text_and_text_values():
    f = Fields("x_RPC.TXT", {"LINE_OFF": "+015834.00 pixels", "E": "  ", "S": " a b ",
                             "N": "abc", "I": "12", "big": 10**400, "L": [1, "2", 3.5],
                             "bad": [[1.0], 2.0]})
    assert f.number("LINE_OFF", from_text=True) == 15834.0
    assert f.number("I", integer=True, from_text=True) == 12
    assert f.text("S") == "a b" and f.text("absent", None) is None
    assert f.numbers("L").tolist() == [1.0, 2.0, 3.5]
    for call, problem in [
        (lambda: f.number("E", from_text=True), "E: has no value"),
        (lambda: f.text("E"), "E: has no value"),
        (lambda: f.number("N", from_text=True), "N: must be a number, got 'abc'"),
        (lambda: f.number("LINE_OFF"), "must be a number, got a string"),  # not from_text
        (lambda: f.number("big"), "big: must be finite"),
        (lambda: f.numbers("bad"), "bad: must be an array of numbers"),
    ]:
        with pytest.raises(MetadataFieldError, match=problem):
            call()
