"""The progress bar of long writes: tqdm on a terminal, no carriage-return frames elsewhere."""

from __future__ import annotations

import io
import warnings

import numpy as np
import rasterio

import geoblock
from geoblock.io._progress import Progress
from geoblock.testing.synthetic import AffineCamera


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_not_a_terminal_writes_one_summary_line():
    stream = io.StringIO()
    with Progress(5, True, file=stream) as bar:
        for _ in range(5):
            bar.update()
        assert stream.getvalue() == ""  # no frames while running
    text = stream.getvalue()
    assert "\r" not in text
    assert text.count("\n") == 1 and text.startswith("writing: 5/5 chunks in ")


def test_disabled_writes_nothing():
    for stream in (io.StringIO(), _Terminal()):
        bar = Progress(3, False, file=stream)
        bar.update(3)
        bar.close()
        assert stream.getvalue() == "" and not bar.interactive


def test_terminal_gets_a_tqdm_bar():
    stream = _Terminal()
    bar = Progress(4, True, file=stream)
    assert bar.interactive
    bar.update(4)
    bar.close()
    bar.close()  # idempotent
    text = stream.getvalue()
    assert "4/4" in text and "100%" in text


def _image(path, shape):
    data = (np.arange(shape[0] * shape[1]) % 251).astype(np.uint8).reshape((1,) + shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0], count=1,
                           dtype="uint8") as ds:
            ds.write(data)
    return str(path)


def test_cli_ortho_and_mosaic_write_no_carriage_returns(tmp_path):
    """Through click's runner (not a terminal) the default --progress writes no frames."""
    from click.testing import CliRunner

    from geoblock.cli.main import build_cli

    runner, cli = CliRunner(), build_cli()
    model = AffineCamera.example((60, 80))
    model_path = str(geoblock.write_model(model, tmp_path / "model.json"))
    image = _image(tmp_path / "scene.tif", (60, 80))
    out = tmp_path / "ortho.tif"
    result = runner.invoke(cli, ["ortho", image, str(out), "--dem", "const:150", "--model",
                                 model_path, "--chunks", "16", "--scheduler", "synchronous"])
    assert result.exit_code == 0, result.output
    assert "\r" not in result.output and "\r" not in result.stderr
    assert result.stderr.count("chunks in ") == 1  # the one summary line
    result = runner.invoke(cli, ["mosaic", str(tmp_path / "mosaic.tif"), str(out), str(out),
                                 "--scheduler", "synchronous"])
    assert result.exit_code == 0, result.output
    assert "\r" not in result.output and "\r" not in result.stderr
