"""Malformed point files give a PointFileError naming the file (issue 12, items 5 and 6)."""

import io

import pytest

from geoblock.errors import GeoblockError
from geoblock.io import read_points
from geoblock.io.points import PointFileError


def test_duplicated_column_is_refused_naming_file_and_column(tmp_path):
    path = tmp_path / "dup.csv"
    path.write_text("id,lon,lat,h,h\np1,7.0,43.7,100,200\n")
    with pytest.raises(PointFileError, match=r"dup\.csv.*duplicated column\(s\) \['h'\]"):
        read_points(path, required=("lon", "lat", "h"))


def test_several_duplicated_columns_are_all_named(tmp_path):
    path = tmp_path / "dup2.csv"
    path.write_text("id,row,col,row,id,kind\na,1,2,3,b,gcp\n")
    with pytest.raises(PointFileError, match=r"dup2\.csv.*\['id', 'row'\]"):
        read_points(path)


def test_duplicated_column_after_stripping_spaces_is_refused():
    with pytest.raises(PointFileError, match=r"<stream>.*\['lon'\]"):
        read_points(io.StringIO("lon, lon ,lat\n1,2,3\n"))


def test_non_utf8_file_is_a_point_file_error_naming_the_file(tmp_path):
    path = tmp_path / "latin1.csv"
    path.write_bytes("id,lon,lat,h\nSaint-Étienne,4.39,45.43,500\n".encode("latin-1"))
    with pytest.raises(PointFileError, match=r"latin1\.csv: not UTF-8") as info:
        read_points(path, required=("lon", "lat", "h"))
    assert isinstance(info.value, GeoblockError)


def test_non_utf8_binary_stream_is_a_point_file_error():
    stream = io.TextIOWrapper(io.BytesIO(b"id,lon\n\xff\xfe,1\n"), encoding="utf-8")
    with pytest.raises(PointFileError, match="not UTF-8"):
        read_points(stream)


def test_utf8_bom_and_non_ascii_ids_still_read(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes("\ufeffid,lon,lat,h\nSaint-Étienne,4.39,45.43,500\n".encode())
    pts = read_points(path, required=("lon", "lat", "h"))
    assert pts["id"].tolist() == ["Saint-Étienne"] and pts["h"].tolist() == [500.0]
