"""Accuracy figures render (Agg) to PNG with the artists the papers' conventions call for."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.quiver import Quiver

from geoblock.errors import ObservationError, ShapeMismatchError
from geoblock.report import (
    error_vector_plot,
    residual_vs_distance,
    rmse_vs_gcp_count,
    save_figure,
    to_local_en,
)
from geoblock.report.figures import nice_number

PNG = b"\x89PNG\r\n\x1a\n"


def _markers(ax, marker):
    """Data points drawn with ``marker`` (one Line2D per point kind)."""
    return sum(len(line.get_xdata()) for line in ax.get_lines()
               if line.get_marker() == marker and line.get_linestyle() == "None")


@pytest.fixture
def points():
    rng = np.random.default_rng(2)
    n = 20
    kind = np.array(["GCP"] * 6 + ["ICP"] * 11 + ["TP"] * 2 + ["ICTP"])
    return (rng.uniform(0, 10000, n), rng.uniform(0, 10000, n), rng.normal(0, 1.5, n),
            rng.normal(0, 1.5, n), kind)


def test_error_vectors_triangles_for_control_circles_for_checks(points, tmp_path):
    e, n, de, dn, kind = points
    de[3] = np.nan  # a GCP without an error: a marker, no vector
    fig = error_vector_plot(e, n, de, dn, kind, scale=500, scale_bar=2.0, title="strip 1",
                            path=tmp_path / "vectors.png")
    ax = fig.axes[0]
    assert _markers(ax, "^") == 6 + 2  # GCPs and TPs
    assert _markers(ax, "o") == 11 + 1  # ICPs and ICTPs
    quiver = next(c for c in ax.collections if isinstance(c, Quiver))
    assert quiver.N == 19 and quiver.scale == pytest.approx(1 / 500)
    assert "×500" in ax.get_title() and "strip 1" in ax.get_title()
    assert ax.get_xlabel() == "E (m)" and ax.get_ylabel() == "N (m)"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["GCP (6)", "ICP (11)", "TP (2)", "ICTP (1)"]
    key = next(a for a in ax.artists if hasattr(a, "U"))
    assert key.U == 2.0 and "2 m error" in key.text.get_text()
    data = (tmp_path / "vectors.png").read_bytes()
    assert data.startswith(PNG) and len(data) > 10_000


def test_error_vectors_in_image_space_point_down_the_rows(points):
    col, row, v_col, v_row, kind = points
    fig = error_vector_plot(col, row, v_col, v_row, kind, scale_bar=0.5, unit="px",
                            y_down=True, xlabel="col (px)", ylabel="row (px)")
    ax = fig.axes[0]
    assert ax.yaxis_inverted() and not ax.xaxis_inverted()
    key = next(a for a in ax.artists if hasattr(a, "U"))
    assert "0.5 px error" in key.text.get_text()
    assert not error_vector_plot(col, row, v_col, v_row, kind).axes[0].yaxis_inverted()


def test_error_vector_default_scale(points):
    e, n, de, dn, kind = points
    fig = error_vector_plot(e, n, de, dn, kind)
    quiver = next(c for c in fig.axes[0].collections if isinstance(c, Quiver))
    scale = 1 / quiver.scale
    assert scale == nice_number(scale)  # a 1-2-5 number
    p95 = np.percentile(np.hypot(de, dn), 95)
    assert 0.05 < scale * p95 / 10000 < 0.13  # the 95th-percentile error is ~12 % of the extent


def test_error_vector_errors(points):
    e, n, de, dn, kind = points
    with pytest.raises(ShapeMismatchError, match="differ in length"):
        error_vector_plot(e, n[:-1], de, dn, kind)
    with pytest.raises(ObservationError, match="unknown point kind"):
        error_vector_plot(e, n, de, dn, "CHK")
    with pytest.raises(ObservationError, match="no point"):
        error_vector_plot([], [], [], [])


def test_rmse_vs_gcp_count_lines_and_band(tmp_path):
    x = np.array([9, 18, 27, 36, 45])
    rng = np.random.default_rng(0)
    series = {"RPCV-0": (x, 1.25 + rng.normal(0, 0.05, (9, 5))), "RFM-1": (x, 0.6 + 1 / x)}
    fig = rmse_vs_gcp_count(series, title="ICPs", path=tmp_path / "rmse.png")
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_label() in
             ("RPCV-0 (mean of 9)", "RFM-1")]
    assert len(lines) == 2
    assert np.allclose(lines[0].get_ydata(), series["RPCV-0"][1].mean(axis=0))
    assert sum(isinstance(c, PolyCollection) for c in ax.collections) == 1  # one CI band
    assert [t.get_text() for t in ax.get_xticklabels()] == ["9", "18", "27", "36", "45"]
    assert ax.get_ylim()[0] == 0 and "RMSE 2D" in ax.get_ylabel()
    assert (tmp_path / "rmse.png").read_bytes().startswith(PNG)
    bars = rmse_vs_gcp_count(series, band="bars").axes[0]
    assert not any(isinstance(c, PolyCollection) for c in bars.collections)
    assert len(bars.containers) == 1  # the error bars of the repeated series


def test_rmse_vs_gcp_count_errors():
    with pytest.raises(ShapeMismatchError, match="expected \\(3,\\) or \\(R, 3\\)"):
        rmse_vs_gcp_count({"a": ([1, 2, 3], np.ones((4, 2)))})
    with pytest.raises(ObservationError, match="no series"):
        rmse_vs_gcp_count({})


def test_residual_vs_distance_fit(tmp_path):
    d = np.linspace(0, 8000, 30)
    series = {"RPCV-0": (d, 0.4 + 0.1e-3 * d), "RFM-1": (d, np.full(30, 0.6))}
    fig = residual_vs_distance(series, path=tmp_path / "dist.png")
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "fit: slope 0.100 m/km, R² = 1.00" in labels  # exact line: 0.1 m per km
    assert ax.get_xlabel() == "Distance from the image centre (km)"
    assert _markers(ax, "o") == 30 and _markers(ax, "s") == 30
    panels = residual_vs_distance({**series, "CCRS": (d, 0.5 + 0 * d)}, panels=True)
    assert sum(a.get_visible() for a in panels.axes) == 3
    with pytest.raises(ShapeMismatchError, match="differ in length"):
        residual_vs_distance({"x": (d, d[:-1])})


def test_save_figure_svg_and_local_positions(tmp_path, points):
    e, n, de, dn, kind = points
    fig = error_vector_plot(e, n, de, dn, kind)
    path = save_figure(fig, tmp_path / "v.svg")
    assert path.read_text().lstrip().startswith("<?xml")
    east, north = to_local_en([7.0, 7.01], [43.7, 43.7])
    assert abs((east[1] - east[0]) - 805.3) < 1.0 and abs(north[0]) < 0.1  # 0.01 deg at 43.7N


def test_nice_number():
    assert [nice_number(v) for v in (0.7, 3.0, 7.9, 12.0, 480.0)] == [0.5, 2.0, 5.0, 10.0, 200.0]
    assert nice_number(3.0, round_down=False) == 5.0 and nice_number(0.0) == 1.0


def test_correction_curve_plot_band_truth_and_rms(tmp_path):
    from geoblock.report import correction_curve_plot

    t = np.linspace(-2.0, 2.0, 200)
    truth = np.stack([1e-6 * np.sin(2 * np.pi * f * t) for f in (0.5, 1.0, 2.0)], axis=-1)
    value = truth + 1e-7  # a 0.1 urad offset on every axis
    sigma = np.full_like(truth, 5e-8)
    path = tmp_path / "curve.png"
    fig = correction_curve_plot(t, value, sigma, truth, path=path, title="image 1")
    assert path.read_bytes()[:8] == PNG
    axes = fig.get_axes()
    assert [a.get_ylabel() for a in axes] == ["roll (µrad)", "pitch (µrad)", "yaw (µrad)"]
    for ax in axes:
        bands = [c for c in ax.collections if isinstance(c, PolyCollection)]
        assert len(bands) == 1  # the sigma band
        # the band spans +-2 sigma = +-0.1 urad about the recovered curve, in urad
        ys = bands[0].get_paths()[0].vertices[:, 1]
        assert ys.max() - ys.min() == pytest.approx(2.0 + 0.2, abs=0.05)
        labels = ax.get_legend_handles_labels()[1]
        assert any("0.1 µrad RMS" in label for label in labels), labels


def test_correction_curve_plot_errors():
    from geoblock.report import correction_curve_plot

    t = np.arange(5.0)
    with pytest.raises(ShapeMismatchError, match=r"value must be \(5, 3\)"):
        correction_curve_plot(t, np.zeros((4, 3)))
    with pytest.raises(ShapeMismatchError, match=r"truth must be \(5, 3\)"):
        correction_curve_plot(t, np.zeros((5, 3)), truth=np.zeros((5, 2)))
    fig = correction_curve_plot(t, np.zeros(5), axes_names=("along",), unit="m", scale=1.0)
    assert [a.get_ylabel() for a in fig.get_axes()] == ["along (m)"]
