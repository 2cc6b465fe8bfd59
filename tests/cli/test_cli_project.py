"""geoblock project / backproject: CSV in, CSV out, statuses, errors."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest


def _read_csv(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


def _floats(rows, name):
    return np.array([float(r[name]) if r[name] not in ("", "nan") else np.nan for r in rows])


@pytest.fixture
def image_points(tmp_path):
    """A CSV of image points (id, row, col, h, note) spread over the image."""
    rng = np.random.default_rng(1)
    n = 25
    row = rng.uniform(-0.5, 999.5, n)
    col = rng.uniform(-0.5, 1199.5, n)
    h = rng.uniform(-100.0, 2500.0, n)
    path = tmp_path / "image.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "row", "col", "h", "note"])
        for i in range(n):
            values = (float(row[i]), float(col[i]), float(h[i]))
            w.writerow([f"p{i}", *map(repr, values), f"n{i}x"])
    return path, row, col, h


def test_backproject_then_project_round_trip_files(runner, cli, model_path, image_points, tmp_path):
    path, row, col, h = image_points
    ground = tmp_path / "ground.csv"
    result = runner.invoke(cli, ["backproject", model_path, str(path), "-o", str(ground)])
    assert result.exit_code == 0, result.output
    assert result.stdout == "" and result.stderr == ""
    rows = _read_csv(ground.read_text())
    assert list(rows[0]) == ["id", "row", "col", "h", "note", "lon", "lat", "status"]
    assert [r["id"] for r in rows] == [f"p{i}" for i in range(len(row))]
    assert [r["note"] for r in rows] == [f"n{i}x" for i in range(len(row))]
    assert {r["status"] for r in rows} == {"converged"}

    # keep only the ground columns, then project them back
    only_ground = tmp_path / "only_ground.csv"
    with open(only_ground, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["id", "lon", "lat", "h"])
        for r in rows:
            w.writerow([r["id"], r["lon"], r["lat"], r["h"]])
    image = tmp_path / "image_again.csv"
    result = runner.invoke(cli, ["project", model_path, str(only_ground), "--output", str(image)])
    assert result.exit_code == 0, result.output
    back = _read_csv(image.read_text())
    assert list(back[0]) == ["id", "lon", "lat", "h", "row", "col", "status"]
    assert {r["status"] for r in back} == {"converged"}
    np.testing.assert_allclose(_floats(back, "row"), row, rtol=0, atol=1e-6)
    np.testing.assert_allclose(_floats(back, "col"), col, rtol=0, atol=1e-6)


def test_round_trip_stdin_stdout(runner, cli, model_path, image_points):
    path, row, col, h = image_points
    result = runner.invoke(cli, ["backproject", model_path], input=path.read_text())
    assert result.exit_code == 0, result.output
    ground_csv = result.stdout
    # '-' reads standard input too; row/col already in the input are replaced in place
    result = runner.invoke(cli, ["project", model_path, "-"], input=ground_csv)
    assert result.exit_code == 0, result.output
    back = _read_csv(result.stdout)
    assert list(back[0]) == ["id", "row", "col", "h", "note", "lon", "lat", "status"]
    np.testing.assert_allclose(_floats(back, "row"), row, rtol=0, atol=1e-6)
    np.testing.assert_allclose(_floats(back, "col"), col, rtol=0, atol=1e-6)


def test_project_matches_the_model(runner, cli, model_path, affine):
    lon = np.array([7.04, 7.05, 7.06])
    lat = np.array([43.695, 43.70, 43.705])
    h = np.array([0.0, 100.0, 1000.0])
    points = zip(lon.tolist(), lat.tolist(), h.tolist(), strict=True)
    text = "lon,lat,h\n" + "".join(f"{a},{b},{c}\n" for a, b, c in points)
    result = runner.invoke(cli, ["project", model_path], input=text)
    assert result.exit_code == 0, result.output
    rows = _read_csv(result.stdout)
    assert [r["id"] for r in rows] == ["1", "2", "3"]  # made up when absent
    expected = affine.project(lon, lat, h)
    np.testing.assert_array_equal(_floats(rows, "row"), expected.row)
    np.testing.assert_array_equal(_floats(rows, "col"), expected.col)


def test_nan_and_empty_values_are_invalid_input(runner, cli, model_path):
    text = (
        "id,lon,lat,h\n"
        "a,7.05,43.70,100\n"
        "b,,43.70,100\n"
        "c,7.05,nan,100\n"
        "d,7.051,43.701,120\n"
    )
    result = runner.invoke(cli, ["project", model_path], input=text)
    assert result.exit_code == 0, result.output
    assert result.stderr == ""  # NaN in, NaN out: silently
    rows = _read_csv(result.stdout)
    assert [r["status"] for r in rows] == [
        "converged", "invalid_input", "invalid_input", "converged"
    ]
    for r in rows[1:3]:
        assert r["row"] in ("", "nan") and r["col"] in ("", "nan")
    assert np.all(np.isfinite(_floats([rows[0], rows[3]], "row")))

    text = "row,col,h\n10,20,0\n,20,0\n10,20,nan\n"
    result = runner.invoke(cli, ["backproject", model_path], input=text)
    assert result.exit_code == 0, result.output
    rows = _read_csv(result.stdout)
    assert [r["status"] for r in rows] == ["converged", "invalid_input", "invalid_input"]
    assert rows[1]["lon"] in ("", "nan") and rows[2]["lat"] in ("", "nan")


def test_missing_column_is_one_line_error(runner, cli, model_path, tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("id,lon,lat\na,7.05,43.7\n")
    result = runner.invoke(cli, ["project", model_path, str(path)])
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("Error: ")
    assert "bad.csv" in lines[0] and "'h'" in lines[0]
    assert result.stdout == ""


def test_non_numeric_value_names_line_and_column(runner, cli, model_path, tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("row,col,h\n1,2,3\n4,five,6\n")
    result = runner.invoke(cli, ["backproject", model_path, str(path)])
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1
    assert "bad.csv" in lines[0] and "line 3" in lines[0] and "'col'" in lines[0]
    assert "'five'" in lines[0]


def test_missing_points_file(runner, cli, model_path, tmp_path):
    result = runner.invoke(cli, ["project", model_path, str(tmp_path / "none.csv")])
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "none.csv" in lines[0]


def test_header_only_gives_header_only(runner, cli, model_path):
    result = runner.invoke(cli, ["project", model_path], input="id,lon,lat,h\n")
    assert result.exit_code == 0, result.output
    assert result.stdout == "id,lon,lat,h,row,col,status\n"


def test_failed_points_give_status_and_one_warning(runner, cli, tmp_path):
    import geoblock
    from geoblock.testing.synthetic import ConstantVelocityPushbroom

    path = str(geoblock.write_model(ConstantVelocityPushbroom.example(), tmp_path / "pb.json"))
    text = "id,lon,lat,h\nfar,100,-40,0\nnear,7.05,43.70,100\n"
    result = runner.invoke(cli, ["project", path], input=text)
    assert result.exit_code == 0, result.output
    rows = _read_csv(result.stdout)
    assert rows[0]["status"] == "diverged" and rows[0]["row"] == "nan"
    assert rows[1]["status"] == "converged" and np.isfinite(float(rows[1]["row"]))
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("Warning: ") and "1 of 2 points" in lines[0]
    result = runner.invoke(cli, ["-q", "project", path], input=text)
    assert result.exit_code == 0 and result.stderr == ""


def test_terminal_stdin_is_a_usage_error(monkeypatch):
    import click

    from geoblock.cli.options import points_source

    class _Tty(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr("sys.stdin", _Tty())
    with pytest.raises(click.UsageError, match="standard input is a terminal"):
        points_source("-")
    assert points_source("points.csv") == "points.csv"


def test_unwritable_output_is_one_line_error(runner, cli, model_path, tmp_path):
    out = tmp_path / "no-such-dir" / "out.csv"
    result = runner.invoke(cli, ["project", model_path, "-o", str(out)], input="lon,lat,h\n")
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "out.csv" in lines[0]
