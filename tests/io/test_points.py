import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoblock.io import read_points, write_points
from geoblock.io.points import PointFileError


def test_read_points_types_and_defaults():
    text = "id,lon,lat,h,kind\np1,7.0,43.7,100,gcp\np2,7.1,43.8,,icp\n"
    pts = read_points(io.StringIO(text), required=("lon", "lat", "h"), optional={"sigma_row": 0.5})
    assert pts["id"].tolist() == ["p1", "p2"]
    assert pts["kind"].tolist() == ["gcp", "icp"]
    assert pts["lon"].dtype == np.float64 and np.isnan(pts["h"][1])
    assert pts["sigma_row"].tolist() == [0.5, 0.5]


def test_read_points_errors(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("lon,lat\n1,2\n")
    with pytest.raises(PointFileError, match=r"p\.csv: missing column\(s\) \['h'\]"):
        read_points(path, required=("lon", "lat", "h"))
    path.write_text("lon,lat,h\n1,2,3\n1,x,3\n")
    with pytest.raises(PointFileError, match=r"p\.csv, line 3, column 'lat': 'x' is not a number"):
        read_points(path, required=("lon", "lat", "h"))
    path.write_text("lon,lat,h\n1,2\n")
    with pytest.raises(PointFileError, match="line 2: 2 fields but the header has 3"):
        read_points(path)
    with pytest.raises(Exception, match="cannot read point file"):
        read_points(tmp_path / "missing.csv")


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=0, max_size=20))
def test_write_read_round_trip_is_exact(values):
    buf = io.StringIO()
    write_points(buf, {"id": [str(i) for i in range(len(values))], "row": np.array(values, float)})
    buf.seek(0)
    back = read_points(buf, required=("row",))
    assert back["row"].tolist() == values


def test_other_columns_pass_through_as_written_and_lines_count_blank_lines(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("lon,lat,h,code\n7.05,43.7,100,007\n")
    pts = read_points(path, required=("lon", "lat", "h"))
    assert pts["code"].tolist() == ["007"] and pts["h"].tolist() == [100.0]
    path.write_text("lon,lat,h\n\n7.05,43.7,abc\n")
    with pytest.raises(PointFileError, match="line 3, column 'h'"):
        read_points(path, required=("lon", "lat", "h"))


def test_write_points_error_is_a_geoblock_error(tmp_path):
    from geoblock.errors import GeoblockIOError

    with pytest.raises(GeoblockIOError, match="cannot write point file"):
        write_points(tmp_path / "missing" / "out.csv", {"row": np.zeros(1)})
