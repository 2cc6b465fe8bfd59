"""Accuracy statistics: definitions on hand-computed cases, grouping, ICTP relative accuracy, CIs.

``AccuracyStats.from_errors``'s basic definition is also checked in test_resect.py
(``test_accuracy_stats_definition``); these tests cover the rest.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from geoblock import coords
from geoblock.adjust import (
    AccuracyStats,
    ImageResidualStats,
    PointErrors,
    confidence_interval,
    distance_from_image_centre,
    ground_errors,
    ictp_accuracy,
)
from geoblock.dem import ConstantDem
from geoblock.errors import ObservationError, ShapeMismatchError
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

# three points with errors (3, 4), (-4, 0), (0, -2) metres: computed by hand
DE = [3.0, -4.0, 0.0]
DN = [4.0, 0.0, -2.0]


def test_hand_computed_ground_statistics():
    s = AccuracyStats.from_errors(DE, DN)
    assert s.n == 3
    assert math.isclose(s.rmse_e, math.sqrt(25 / 3)) and math.isclose(s.rmse_n, math.sqrt(20 / 3))
    assert math.isclose(s.rmse_2d, math.sqrt(15.0))  # sqrt(RMSE_E^2 + RMSE_N^2)
    assert math.isclose(s.rmse_1d, math.sqrt(7.5))  # RMSE_2D / sqrt(2)
    assert math.isclose(s.mean_e, -1 / 3) and math.isclose(s.mean_n, 2 / 3)
    assert s.max_e == -4.0 and s.max_n == 4.0 and s.max_2d == 5.0  # signed per axis
    d = s.as_dict()
    assert d["rmse_1d"] == s.rmse_1d and d["n"] == 3


def test_empty_and_nan_errors_give_nan_statistics():
    s = AccuracyStats.from_errors([np.nan], [1.0])
    assert s.n == 0 and math.isnan(s.rmse_2d) and math.isnan(s.rmse_1d)


def test_image_residual_statistics():
    s = ImageResidualStats.from_residuals([0.3, -0.4], [0.4, 0.0])
    assert s.n == 2
    assert math.isclose(s.rmse_row, math.sqrt(0.125)) and math.isclose(s.rmse_col, math.sqrt(0.08))
    assert math.isclose(s.rmse_2d, math.sqrt(0.205))
    assert s.max_row == -0.4 and s.max_col == 0.4 and math.isclose(s.max_2d, 0.5)


def test_mismatched_shapes_raise():
    with pytest.raises(ShapeMismatchError, match=r"de has shape \(3,\) but dn has shape \(2,\)"):
        AccuracyStats.from_errors(DE, DN[:2])
    with pytest.raises(ShapeMismatchError, match="row has shape"):
        ImageResidualStats.from_residuals([1.0], [1.0, 2.0])
    with pytest.raises(ShapeMismatchError, match="differ in shape"):
        ground_errors([7.0, 7.1], [43.0, 43.0], [7.0], [43.0])
    with pytest.raises(ShapeMismatchError, match=r"e has shape \(2,\), expected \(3,\)"):
        PointErrors(["a", "b", "c"], "ICP", [1.0, 2.0], [1.0, 2.0, 3.0])


def test_ground_errors_in_local_metres():
    """Points placed at known east/north/up offsets from reference points come back exactly."""
    lon_ref = np.array([7.05, -120.3, 151.2])
    lat_ref = np.array([43.7, 36.9, -33.9])
    h_ref = np.array([100.0, 1500.0, 20.0])
    offsets = np.array([[3.0, -4.0, 1.0], [-250.0, 10.0, 0.0], [0.5, 0.25, -2.0]])
    lon, lat, h = [], [], []
    for i in range(3):
        g = coords.LocalFrame(lon_ref[i], lat_ref[i], h_ref[i]).to_geodetic(*offsets[i])
        lon.append(g.lon), lat.append(g.lat), h.append(g.h)
    de, dn, du = ground_errors(lon, lat, lon_ref, lat_ref, h=h, h_ref=h_ref)
    assert np.allclose(np.c_[de, dn, du], offsets, atol=1e-6)
    # planimetric: no estimated heights -> compared at the reference heights, du unknown
    de2, dn2, du2 = ground_errors(lon, lat, lon_ref, lat_ref, h_ref=h_ref)
    assert np.allclose(np.c_[de2, dn2], offsets[:, :2], atol=1e-3) and np.isnan(du2).all()
    de3, _, du3 = ground_errors(lon, lat, lon_ref, lat_ref, h=h)  # at the estimated heights
    assert np.allclose(de3, offsets[:, 0], atol=1e-3) and np.isnan(du3).all()
    s = AccuracyStats.from_ground(lon, lat, lon_ref, lat_ref, h=h, h_ref=h_ref)
    assert math.isclose(s.rmse_e, np.sqrt(np.mean(offsets[:, 0] ** 2)), rel_tol=1e-9)


# --------------------------------------------------------------------------- grouping
@pytest.fixture
def errors():
    return PointErrors(
        id=["g1", "g2", "i1", "i2", "i3", "t1"],
        kind=["GCP", "gcp", "ICP", "ICP", "ICP", "TP"],
        e=[1.0, -1.0, 3.0, -4.0, 0.0, 2.0],
        n=[0.0, 0.0, 4.0, 0.0, -2.0, np.nan],
        row=[0.1, -0.1, 0.5, 0.5, 0.5, 0.2],
        col=[0.0, 0.0, 0.0, 0.0, 0.0, 0.2],
        image=["A", "B", "A", "A", "B", "B"],
    )


def test_statistics_per_kind(errors):
    by_kind = errors.by_kind()
    assert list(by_kind) == ["GCP", "ICP", "TP"]  # POINT_KINDS order, only those present
    assert by_kind["ICP"] == AccuracyStats.from_errors(DE, DN)
    assert by_kind["GCP"].rmse_e == 1.0 and by_kind["GCP"].mean_e == 0.0
    assert by_kind["TP"].n == 0  # its only error is NaN: a group without statistics
    px = errors.by_kind(["ICP"], image_space=True)
    assert list(px) == ["ICP"] and math.isclose(px["ICP"].rmse_row, 0.5)


def test_statistics_per_image_and_pair(errors):
    by_image = errors.by_image()
    assert list(by_image) == ["A", "B"]
    assert by_image["A"].n == 3 and by_image["B"].n == 2  # B's TP has no finite error
    both = errors.by_image_and_kind()
    assert list(both) == [("A", "GCP"), ("A", "ICP"), ("B", "GCP"), ("B", "ICP"), ("B", "TP")]
    assert both[("A", "ICP")] == AccuracyStats.from_errors([3.0, -4.0], [4.0, 0.0])
    assert errors.select(kind="ICP", image="B").id.tolist() == ["i3"]
    assert errors.stats().n == 5 and errors.residual_stats().n == 6


def test_unknown_kinds_and_empty_groups_raise(errors):
    with pytest.raises(ObservationError, match=r"kind\(s\) \['CHECK'\] \(points p2\)"):
        PointErrors(["p1", "p2"], ["GCP", "check"], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(ObservationError, match=r"no point in group\(s\) \['ICTP'\]"):
        errors.by_kind(["ICP", "ICTP"])
    with pytest.raises(ObservationError, match="unknown point kind"):
        errors.by_kind(["XYZ"])
    with pytest.raises(ObservationError, match=r"no point in group\(s\) \['C'\]"):
        errors.by_image(["A", "C"])


def test_point_errors_from_ground():
    ref = coords.LocalFrame(7.05, 43.7, 50.0)
    true = ref.to_geodetic([0.0, 1000.0], [0.0, 500.0], [0.0, 0.0])
    est = ref.to_geodetic([0.5, 1000.0], [0.0, 498.0], [0.0, 0.0])
    pe = PointErrors.from_ground(["a", "b"], ["GCP", "ICP"], est.lon, est.lat, true.lon,
                                 true.lat, h=est.h, h_ref=true.h)
    # in each reference point's own frame (1 km away the axes turn by 1.6e-4 rad)
    assert np.allclose(pe.e, [0.5, 0.0], atol=1e-3) and np.allclose(pe.n, [0.0, -2.0], atol=1e-6)
    assert np.isnan(pe.row).all() and pe.image.tolist() == ["", ""]


# --------------------------------------------------------------------------- ICTP
def _shifted_affine(d_row=0.0, d_col=0.0):
    """AffineCamera.example with its image shifted: 0.5 px/m, so 1 px = 2 m on the ground."""
    base = AffineCamera.example()
    values = base.parameters.values.copy()
    values[0] += d_row
    values[4] += d_col
    return base.with_parameters(values)


def _measure(models, ground, ids):
    """Exact image coordinates of ground points in each image, as (id, image, row, col)."""
    id_, image, row, col = [], [], [], []
    for name, model in models.items():
        r, c = model.project(ground.lon, ground.lat, ground.h)
        id_ += ids
        image += [name] * len(ids)
        row.append(r), col.append(c)
    return id_, image, np.concatenate(row), np.concatenate(col)


@pytest.fixture(scope="module")
def ictp_ground():
    rng = np.random.default_rng(3)
    model = AffineCamera.example()
    g = model.backproject(rng.uniform(0, 999, 8), rng.uniform(0, 1199, 8), 250.0)
    return g, [f"c{i}" for i in range(8)]


def test_ictp_of_a_perfect_pair_is_zero(ictp_ground):
    ground, ids = ictp_ground
    models = {"A": AffineCamera.example(), "B": _shifted_affine(30.0, -40.0)}
    res = ictp_accuracy(models, *_measure(models, ground, ids), ConstantDem(250.0))
    assert len(res) == 8 and (res.image_a == "A").all() and (res.image_b == "B").all()
    assert np.max(res.distance_3d) < 1e-3  # metres (localize tolerance 1 mm)
    assert (res.status_a == 0).all() and res.unpaired.size == 0


def test_ictp_known_image_offset_gives_the_predicted_distance(ictp_ground):
    """Image B measured 1 px right and 1 px down: col_e = 0.5 px/m, row_n = -0.5 px/m, so
    the point from B lies 2 m east and 2 m south of the point from A (on a constant DEM)."""
    ground, ids = ictp_ground
    models = {"A": AffineCamera.example(), "B": AffineCamera.example()}
    id_, image, row, col = _measure(models, ground, ids)
    in_b = np.array(image) == "B"
    col = col + in_b * 1.0
    row = row + in_b * 1.0
    res = ictp_accuracy(models, id_, image, row, col, ConstantDem(250.0))
    assert np.allclose(res.e, 2.0, atol=2e-3) and np.allclose(res.n, -2.0, atol=2e-3)
    assert np.allclose(res.u, 0.0, atol=2e-3)
    assert np.allclose(res.distance_2d, 2 * math.sqrt(2), atol=2e-3)
    s = res.stats
    assert math.isclose(s.rmse_e, 2.0, abs_tol=2e-3) and math.isclose(s.rmse_2d, 2 * math.sqrt(2),
                                                                      abs_tol=2e-3)
    assert math.isclose(res.rmse_3d, 2 * math.sqrt(2), abs_tol=2e-3)
    pe = res.as_point_errors()
    assert set(pe.kind) == {"ICTP"} and set(pe.image) == {"A & B"}


def test_ictp_pushbroom_pair_and_three_images():
    a = ConstantVelocityPushbroom.example(roll=0.002)
    b = ConstantVelocityPushbroom.example(roll=-0.003)
    c = ConstantVelocityPushbroom.example(roll=0.0)
    rng = np.random.default_rng(5)
    ground = a.backproject(rng.uniform(100, 700, 6), rng.uniform(300, 700, 6), 800.0)
    ids = [f"t{i}" for i in range(6)]
    models = {"A": a, "B": b, "C": c}
    id_, image, row, col = _measure(models, ground, ids)
    keep = ~((np.array(image) == "C") & np.isin(id_, ["t0", "t1"]))  # t0, t1 not in C
    res = ictp_accuracy(models, np.array(id_)[keep], np.array(image)[keep], row[keep],
                        col[keep], 800.0)
    assert len(res) == 6 + 4 + 4  # A-B all, A-C and B-C without t0, t1
    assert np.max(res.distance_3d) < 1e-3
    assert list(res.by_pair()) == [("A", "B"), ("A", "C"), ("B", "C")]


def test_ictp_input_errors(ictp_ground):
    ground, ids = ictp_ground
    models = {"A": AffineCamera.example(), "B": AffineCamera.example()}
    id_, image, row, col = _measure(models, ground, ids)
    with pytest.raises(ObservationError, match=r"image\(s\) \['Z'\] that are not in the models"):
        ictp_accuracy(models, id_, ["Z"] + image[1:], row, col, 0.0)
    # the message names image and point ("A: c0"), not "Ac0"
    twice = r"measured more than once in one image: \[.A: c0.\]"
    with pytest.raises(ObservationError, match=twice):
        ictp_accuracy(models, ["c0", "c0"] + id_[2:], image, row, col, 0.0)
    with pytest.raises(ObservationError, match="no point is measured in two images"):
        ictp_accuracy(models, id_[:8], image[:8], row[:8], col[:8], 0.0)
    with pytest.raises(ShapeMismatchError, match="row has shape"):
        ictp_accuracy(models, id_, image, row[:-1], col, 0.0)
    res = ictp_accuracy(models, id_[:-1], image[:-1], row[:-1], col[:-1], 250.0)
    assert res.unpaired.tolist() == ["c7"] and len(res) == 7


# --------------------------------------------------------------------------- helpers
def test_distance_from_image_centre():
    model = AffineCamera.example()
    centre = model.backproject(499.5, 599.5, 300.0)
    frame = coords.LocalFrame(float(centre.lon), float(centre.lat), 300.0)
    pts = frame.to_geodetic([0.0, 1000.0, 0.0], [0.0, 0.0, -2000.0], [0.0, 0.0, 0.0])
    d = distance_from_image_centre(model, pts.lon, pts.lat, pts.h)
    # the tangent plane drops 0.3 m below h = 300 at 2 km: the oblique camera's centre (0.05
    # px/m of height, 2 m pixels) moves by 3 cm there
    assert np.allclose(d, [0.0, 1000.0, 2000.0], atol=0.05)
    assert abs(d[1] - 1000.0) < 0.01


def test_confidence_interval_hand_computed():
    ci = confidence_interval([1.0, 2.0, 3.0, 4.0, 5.0])
    half = 2.7764451 * math.sqrt(2.5) / math.sqrt(5)  # t(0.975, 4 dof) from tables
    assert ci.n == 5 and ci.mean == 3.0 and math.isclose(ci.std, math.sqrt(2.5))
    assert math.isclose(ci.low, 3.0 - half, rel_tol=1e-6) and math.isclose(ci.high, 3 + half,
                                                                            rel_tol=1e-6)
    p = confidence_interval([1.0, 2.0, 3.0, 4.0, 5.0], method="percentile", level=0.9)
    assert math.isclose(p.low, 1.2) and math.isclose(p.high, 4.8)  # linear interpolation


def test_confidence_interval_columns_nan_and_errors():
    v = np.array([[1.0, 5.0, np.nan], [3.0, np.nan, np.nan], [2.0, 7.0, 4.0]])
    ci = confidence_interval(v)
    assert ci.n.tolist() == [3, 2, 1]
    assert np.allclose(ci.mean, [2.0, 6.0, 4.0])
    assert np.isnan(ci.low[2]) and np.isnan(ci.high[2])  # one value: no interval
    with pytest.raises(ObservationError, match="level must be in"):
        confidence_interval([1.0, 2.0], level=95)
    with pytest.raises(ObservationError, match="method must be"):
        confidence_interval([1.0, 2.0], method="bootstrap")
    with pytest.raises(ShapeMismatchError, match="R >= 1"):
        confidence_interval([])


def test_t_interval_covers_the_true_mean_95_percent_of_the_time():
    rng = np.random.default_rng(11)
    samples = rng.normal(1.3, 0.4, size=(6, 4000))  # 4000 experiments of 6 runs
    ci = confidence_interval(samples, level=0.95)
    coverage = np.mean((ci.low <= 1.3) & (1.3 <= ci.high))
    assert 0.94 < coverage < 0.96, coverage
    runs = confidence_interval(samples.T[:, :1].repeat(1, 1), method="percentile")
    assert runs.n[0] == 4000
    inside = np.mean((samples[0] >= runs.low[0]) & (samples[0] <= runs.high[0]))
    assert math.isclose(inside, 0.95, abs_tol=0.002)


def test_ictp_pairs_follow_the_models_order_whatever_the_measurements_order():
    """The pairs of images come in the models' order (a before b), then by point id, as the
    every-pair-of-images enumeration gave them, with the measurements given in any order."""
    a = ConstantVelocityPushbroom.example(roll=0.002)
    b = ConstantVelocityPushbroom.example(roll=-0.003)
    c = ConstantVelocityPushbroom.example(roll=0.0)
    rng = np.random.default_rng(7)
    ground = a.backproject(rng.uniform(100, 700, 9), rng.uniform(300, 700, 9), 800.0)
    ids = [f"t{i}" for i in (3, 1, 7, 0, 8, 2, 6, 4, 5)]
    models = {"C": c, "A": a, "B": b}
    id_, image, row, col = _measure(models, ground, ids)
    id_, image = np.array(id_), np.array(image)
    keep = ~((image == "A") & np.isin(id_, ["t0", "t5"]))
    shuffle = rng.permutation(np.flatnonzero(keep))
    res = ictp_accuracy(models, id_[shuffle], image[shuffle], row[shuffle], col[shuffle], 800.0)
    expected = []
    names = list(models)
    for i, name_a in enumerate(names):
        for name_b in names[i + 1:]:
            common = sorted(set(id_[keep & (image == name_a)]) & set(id_[keep & (image == name_b)]))
            expected += [(p, name_a, name_b) for p in common]
    assert list(zip(res.id.tolist(), res.image_a.tolist(), res.image_b.tolist())) == expected
    assert np.max(res.distance_3d) < 1e-3
