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
