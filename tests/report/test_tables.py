"""Accuracy tables: Markdown and CSV parse back to the statistics they show."""

from __future__ import annotations

import csv
import doctest
import io
import math

import numpy as np
import pytest

import geoblock.report.tables
from geoblock.adjust import AccuracyStats, ImageResidualStats, PointErrors
from geoblock.errors import GeoblockIOError, ObservationError
from geoblock.report import AGUILAR_COLUMNS, comparison_table, stats_table, write_table


@pytest.fixture
def by_kind():
    pe = PointErrors(["g1", "g2", "i1", "i2", "i3"], ["GCP", "GCP", "ICP", "ICP", "ICP"],
                     [1.0, -1.0, 3.0, -4.0, 0.0], [0.5, 0.5, 4.0, 0.0, -2.0],
                     row=[0.1, 0.2, 0.3, 0.4, 0.5], col=[0.0, 0.1, 0.0, -0.1, 0.0])
    return pe.by_kind(), pe.by_kind(image_space=True)


def parse_markdown(text):
    """Rows of a Markdown table as lists of cell strings (header first, separator dropped)."""
    lines = [ln for ln in text.splitlines() if ln.startswith("|")]
    rows = [[c.strip() for c in ln.strip("|").split(" | ")] for ln in lines]
    assert all(set(c) <= set(":-") for c in rows[1])
    return [rows[0], *rows[2:]]


def test_markdown_parses_back(by_kind):
    ground, _ = by_kind
    text = stats_table(ground, labels=("kind",), title="ICP and GCP accuracy")
    assert text.startswith("**ICP and GCP accuracy**\n\n|")
    header, *rows = parse_markdown(text)
    assert header[:4] == ["kind", "n", "RMSE E (m)", "RMSE N (m)"]
    assert [r[0] for r in rows] == ["GCP", "ICP"]
    icp = dict(zip(header, rows[1], strict=True))
    assert icp["n"] == "3" and icp["RMSE E (m)"] == f"{math.sqrt(25 / 3):.2f}" == "2.89"
    assert icp["Max E (m)"] == "-4.00" and icp["Max 2D (m)"] == "5.00"


def test_csv_parses_back_at_full_precision(by_kind):
    ground, _ = by_kind
    rows = list(csv.DictReader(io.StringIO(stats_table(ground, labels=("kind",), fmt="csv"))))
    assert [r["kind"] for r in rows] == ["GCP", "ICP"]
    for row in rows:
        s = ground[row["kind"]]
        assert int(row["n"]) == s.n
        assert float(row["RMSE E (m)"]) == s.rmse_e and float(row["Max N (m)"]) == s.max_n
        assert float(row["RMSE 2D (m)"]) == s.rmse_2d


def test_aguilar_columns_and_rmse_1d(by_kind):
    ground, _ = by_kind
    table = {("RPCV-0", "9"): ground["ICP"], ("RPCV-1", "9"): ground["GCP"]}
    header, *rows = parse_markdown(stats_table(table, labels=("model", "GCPs"),
                                               columns=AGUILAR_COLUMNS, decimals=3))
    assert header == ["model", "GCPs", "n", "RMSE E (m)", "RMSE N (m)", "RMSE 2D (m)",
                      "Max E (m)", "Max N (m)", "Mean E (m)", "Mean N (m)"]
    assert rows[0][:2] == ["RPCV-0", "9"] and rows[0][5] == f"{math.sqrt(15):.3f}"
    one = parse_markdown(stats_table(table, labels=("model", "GCPs"), columns=["rmse_1d"]))
    assert one[1][2] == f"{math.sqrt(7.5):.2f}"


def test_image_residual_table_has_pixel_units(by_kind):
    _, pixel = by_kind
    header, *rows = parse_markdown(stats_table(pixel, labels=("kind",)))
    assert "RMSE row (px)" in header and "RMSE 2D (px)" in header
    assert float(rows[0][header.index("RMSE row (px)")]) == round(pixel["GCP"].rmse_row, 2)


def test_teo_comparison_table():
    block = AccuracyStats.from_errors([2.0, -2.0], [1.0, 1.0])
    single = AccuracyStats.from_errors([10.0, -12.0, 11.0], [8.0, 9.0, -9.0])
    rows = {
        ("MBA", "Block", "TP"): {"Strips 1 & 2": block, "Strips 2 & 3": block},
        ("MBA", "Single", "ICTP"): {"Strips 1 & 2": single},
    }
    text = comparison_table(rows, fmt="csv")
    parsed = list(csv.reader(io.StringIO(text)))
    assert parsed[0] == ["method", "adjustment", "kind",
                         "Strips 1 & 2 n", "Strips 1 & 2 RMSE E (m)", "Strips 1 & 2 RMSE N (m)",
                         "Strips 2 & 3 n", "Strips 2 & 3 RMSE E (m)", "Strips 2 & 3 RMSE N (m)"]
    assert parsed[1][:4] == ["MBA", "Block", "TP", "2"] and float(parsed[1][4]) == 2.0
    assert parsed[2][3] == "3" and float(parsed[2][4]) == single.rmse_e
    assert parsed[2][6:] == ["", "", ""]  # no strips 2 & 3 for that row
    md = parse_markdown(comparison_table(rows, counts=False))
    assert md[2] == ["MBA", "Single", "ICTP", f"{single.rmse_e:.2f}", f"{single.rmse_n:.2f}",
                     "—", "—"]


def test_nan_statistics_are_shown_as_missing():
    empty = {"TP": AccuracyStats.from_errors([np.nan], [np.nan])}
    assert parse_markdown(stats_table(empty, labels=("kind",)))[1][1:3] == ["0", "—"]
    row = next(csv.DictReader(io.StringIO(stats_table(empty, labels=("kind",), fmt="csv"))))
    assert math.isnan(float(row["RMSE E (m)"]))


def test_table_errors(by_kind):
    ground, pixel = by_kind
    with pytest.raises(ObservationError, match="no statistics given"):
        stats_table({})
    with pytest.raises(ObservationError, match="all be AccuracyStats or all ImageResidual"):
        stats_table({"a": ground["GCP"], "b": pixel["GCP"]})
    with pytest.raises(ObservationError, match=r"unknown column\(s\) \['rmse_row'\]"):
        stats_table(ground, columns=["rmse_e", "rmse_row"])
    with pytest.raises(ObservationError, match="has 2 part"):
        stats_table({("a", "b"): ground["GCP"]}, labels=("kind",))
    with pytest.raises(ObservationError, match="fmt must be one of"):
        stats_table(ground, fmt="latex")
    with pytest.raises(ObservationError, match="no column group"):
        comparison_table({("MBA", "Block", "TP"): {}})
    assert isinstance(pixel["GCP"], ImageResidualStats)


def test_write_table_is_atomic(tmp_path, by_kind):
    ground, _ = by_kind
    text = stats_table(ground, labels=("kind",), fmt="csv")
    path = write_table(text, tmp_path / "acc.csv")
    assert path.read_text(encoding="utf-8") == text
    assert [p.name for p in tmp_path.iterdir()] == ["acc.csv"]  # no temporary left behind
    write_table("new\n", path)
    assert path.read_text() == "new\n"
    with pytest.raises(GeoblockIOError, match="does not exist"):
        write_table(text, tmp_path / "missing" / "acc.csv")


def test_docstring_examples_run():
    result = doctest.testmod(geoblock.report.tables, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted >= 1 and result.failed == 0
