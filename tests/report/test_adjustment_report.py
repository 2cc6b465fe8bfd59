"""The report of a block adjustment lives in geoblock.report.adjustment; the 0.1 module
geoblock.adjust.output forwards to it with a deprecation warning."""

from __future__ import annotations

import pytest

import geoblock.report
from geoblock.errors import GeoblockDeprecationWarning
from geoblock.report import adjustment


@pytest.mark.parametrize("name", ["write_result", "result_dict", "report_markdown"])
def test_old_names_forward_with_a_warning(name):
    import geoblock.adjust.output as old

    with pytest.warns(GeoblockDeprecationWarning, match=f"geoblock.report.adjustment.{name}"):
        moved = getattr(old, name)
    assert moved is getattr(adjustment, name) is getattr(geoblock.report, name)


def test_other_names_are_not_invented():
    import geoblock.adjust.output as old

    with pytest.raises(AttributeError, match="no attribute 'stats_table'"):
        old.stats_table  # noqa: B018


# ------------------------------------------------------------------ issue 28
def _reference_block():
    """An affine block whose GCPs are half surveyed, half from a reference with a common
    error (sigma_shift 2 m), one HCP, and ICPs seen by one image or more."""
    import numpy as np

    from geoblock.adjust.block import Block
    from geoblock.adjust.observations import GroundPoints
    from geoblock.testing.blocks import affine_block

    sb = affine_block((1, 2), gcps=6, icps=8, tps=80, ictps=0, seed=11)
    b = sb.block
    g = b.ground
    gcp = np.flatnonzero(g.kind == "gcp")
    source = np.full(len(g), "survey", dtype=object)
    source[gcp[::2]] = "reference:gri.tif"
    shift = np.where(source == "reference:gri.tif", 2.0, 0.0)
    m = b.measurements
    tp = m.id[m.kind == "tp"][0]
    k = np.flatnonzero(sb.point_id == tp)
    ground = GroundPoints(np.concatenate([g.id, [tp]]), np.concatenate([g.kind, ["hcp"]]),
                          np.concatenate([g.lon, [np.nan]]), np.concatenate([g.lat, [np.nan]]),
                          np.concatenate([g.h, sb.truth_h[k]]),
                          np.concatenate([g.sigma_e, [0.0]]), np.concatenate([g.sigma_n, [0.0]]),
                          np.concatenate([g.sigma_h, [0.3]]),
                          np.concatenate([source.astype(str), ["lidar"]]),
                          np.concatenate([shift, [0.0]]), np.concatenate([shift, [0.0]]), 0.0)
    from geoblock.adjust.observations import ImagePoints

    meas = ImagePoints(m.id, m.image, m.row, m.col, m.sigma_row, m.sigma_col,
                       np.where(m.id == tp, "hcp", m.kind))
    return Block(b.models, meas, ground, b.dem, b.dem_sigma_m)


def test_report_separates_reference_control_and_states_the_accuracy(tmp_path):
    import json

    from geoblock.adjust.block import adjust

    result = adjust(_reference_block())
    text = adjustment.report_markdown(result)
    assert "**GCPs by source**" in text
    assert "| reference:gri.tif |" in text and "| survey |" in text
    assert "## Common error of each control source" in text
    assert "## Height control points" in text
    assert "## Accuracy statements (NSSDA)" in text
    header = ("| image | n ICP | CE90 predicted | CE90 empirical (percentile) | CE90 NSSDA | "
              "CE95 predicted | CE95 empirical | n LE | LE90 predicted | LE90 empirical | "
              "CE90 grid |")
    assert header in text
    assert "| **block** |" in text
    written = adjustment.write_result(result, tmp_path / "out", figures=False)
    report = json.loads(written["report.json"].read_text())
    assert set(report["statistics"]["gcp_by_source"]) == {"reference:gri.tif", "survey"}
    assert report["source_shifts"]["reference:gri.tif"]["prior_sigma_e_m"] == 2.0
    assert report["height_control"]["statistics"]["n"] == 1
    block = report["accuracy_statements"]["block"]
    assert block["n_icp"] > 0 and block["ce90_predicted"] > 0
    assert {p["source"] for p in report["check_points"]} == {"reference:gri.tif", "survey"}
    assert report["check_points"][0]["predicted_covariance_en_m2"] is not None


def test_report_says_le90_is_not_available_without_multi_image_icps():
    import numpy as np

    from geoblock.adjust.block import Block, adjust
    from geoblock.adjust.observations import ImagePoints
    from geoblock.testing.blocks import affine_block

    b = affine_block((1, 2), gcps=5, icps=6, tps=80, ictps=0, seed=7).block
    m = b.measurements
    icp = np.flatnonzero(m.kind == "icp")
    _, first = np.unique(m.id[icp], return_index=True)
    keep = np.ones(len(m), bool)
    keep[icp] = False
    keep[icp[first]] = True
    meas = ImagePoints(m.id[keep], m.image[keep], m.row[keep], m.col[keep], m.sigma_row[keep],
                       m.sigma_col[keep], m.kind[keep])
    text = adjustment.report_markdown(adjust(Block(b.models, meas, b.ground, b.dem)))
    assert "## Accuracy statements (NSSDA)" in text
    assert "LE90 n/a: no ICP measured in two images or more" in text
    row = next(line for line in text.splitlines() if line.startswith("| **block** |"))
    assert "| 0 | n/a | n/a |" in row


def test_without_icps_the_grid_prediction_is_stated():
    import math

    import numpy as np

    from geoblock.adjust.block import Block, adjust
    from geoblock.testing.blocks import affine_block

    b = affine_block((1, 2), gcps=5, icps=0, tps=80, ictps=0, seed=9).block
    result = adjust(Block(b.models, b.measurements, b.ground, b.dem, b.dem_sigma_m))
    st = result.accuracy_statement()
    assert st.n_icp == 0 and math.isnan(st.ce90_predicted) and st.reason == "no ICP"
    assert st.ce90_grid > 0 and st.ce95_grid > st.ce90_grid
    assert set(result.grid_covariance) == set(result.models)
    assert all(c.shape == (81, 2, 2) and np.isfinite(c).all()
               for c in result.grid_covariance.values())
    text = adjustment.report_markdown(result)
    row = next(line for line in text.splitlines() if line.startswith("| **block** |"))
    assert row.rstrip().endswith(f"| {st.ce90_grid:.2f} |")
