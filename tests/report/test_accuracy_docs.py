"""The code blocks of docs/user-guide/accuracy.md run as written, in order."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

PAGE = Path(__file__).resolve().parents[2] / "docs" / "user-guide" / "accuracy.md"


def test_accuracy_page_examples_run(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.S)
    assert len(blocks) >= 8
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, str(PAGE), "exec"), namespace)
    # the values the page states
    assert namespace["s"].n == 3 and round(namespace["s"].rmse_2d, 3) == 3.873
    assert round(namespace["s"].rmse_1d, 3) == 2.739
    ictp = namespace["ictp"]
    assert abs(ictp.stats.rmse_e - 2.5) < 0.05 and ictp.stats.rmse_n < 0.05
    assert np.allclose(namespace["de"], [1.0, -0.5], atol=1e-3)  # local frames turn slightly
    for name in ("accuracy.csv", "vectors.png", "rmse_vs_gcps.png", "residual_vs_distance.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert "| RPCV-0 | 9 |" in capsys.readouterr().out
