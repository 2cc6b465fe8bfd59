"""Never lose a user's file (issue 25): outputs are checked before any work.

* an existing output is refused unless ``--overwrite`` (every command that writes);
* an output that is also an input is refused always, and so are two outputs that are one file;
* an output that cannot be written (missing or read-only directory) fails first, naming the
  user's path;
* ``geoblock mosaic``'s output comes first: the gdalwarp habit of giving it last is caught.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import click
import numpy as np
import pytest
import rasterio
from affine import Affine
from click.testing import CliRunner

import geoblock
from geoblock.cli.main import build_cli
from geoblock.errors import OutputExistsError, OutputIsInputError, OutputPathError
from geoblock.io import open_quietly
from geoblock.io.outputs import check_outputs
from geoblock.testing.synthetic import AffineCamera


@pytest.fixture
def run():
    cli = build_cli()

    def invoke(*args: object):
        return CliRunner().invoke(cli, [str(a) for a in args])

    return invoke


def _ortho(path: Path, west: float, value: int) -> Path:
    """A 10 x 10 uint8 ortho in UTM 31N, 1 m pixels, its left edge at ``west``."""
    with rasterio.open(path, "w", driver="GTiff", width=10, height=10, count=1, dtype="uint8",
                       crs="EPSG:32631", transform=Affine(1, 0, west, 0, -1, 4800000),
                       nodata=0) as ds:
        ds.write(np.full((1, 10, 10), value, np.uint8))
    return path


# ---------------------------------------------------------------------- the library rule
def test_check_outputs(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text("x\n")
    check_outputs({"OUT": tmp_path / "new.csv"}, {"IN": src})  # absent: fine
    check_outputs({"OUT": "-"}, {"IN": "-"})  # standard output and input are no files
    with pytest.raises(OutputExistsError, match="in.csv.*exists; pass --overwrite"):
        check_outputs({"OUT": src})
    check_outputs({"OUT": src}, overwrite=True)
    for same in (src, str(src), tmp_path / "." / "in.csv"):
        with pytest.raises(OutputIsInputError, match="is also an input"):
            check_outputs({"OUT": same}, {"IN": [tmp_path / "other", src]}, overwrite=True)
    (tmp_path / "link.csv").symlink_to(src)
    os.link(src, tmp_path / "hard.csv")
    for alias in ("link.csv", "hard.csv"):  # one file under another name
        with pytest.raises(OutputIsInputError):
            check_outputs({"OUT": tmp_path / alias}, {"IN": src}, overwrite=True)
    with pytest.raises(OutputIsInputError, match="also written as"):
        check_outputs({"-o": tmp_path / "a.csv", "--diagnostics": tmp_path / "a.csv"})
    with pytest.raises(OutputPathError, match="directory .*nodir does not exist"):
        check_outputs({"-o": tmp_path / "nodir" / "a.csv"})
    with pytest.raises(OutputPathError, match="is a directory"):
        check_outputs({"-o": tmp_path}, overwrite=True)
    # directories: created with their parents; a non-empty one needs overwrite
    check_outputs({"DIR": tmp_path / "new" / "deeper"}, directories=["DIR"])
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("x")
    with pytest.raises(OutputExistsError, match="not empty"):
        check_outputs({"DIR": tmp_path / "full"}, directories=["DIR"])
    check_outputs({"DIR": tmp_path / "full"}, directories=["DIR"], overwrite=True)
    with pytest.raises(OutputPathError, match="not a directory"):
        check_outputs({"DIR": src}, directories=["DIR"], overwrite=True)


@pytest.fixture
def readonly_dir(tmp_path):
    """A directory on a read-only file system (a small tmpfs mounted read-only)."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a read-only tmpfs needs root and mount(8)")
    folder = tmp_path / "ro"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k,ro", "tmpfs",
                              str(folder)], capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f"mount refused here: {mounted.stderr.strip()}")
    yield folder
    subprocess.run(["umount", str(folder)], check=False)


def test_a_read_only_directory_is_refused_before_any_work(run, tmp_path, readonly_dir):
    with pytest.raises(OutputPathError, match="read-only file system"):
        check_outputs({"-o": readonly_dir / "tp.csv"})
    points = tmp_path / "p.csv"
    points.write_text("lon,lat,h\n7.0,43.7,100\n")
    model = geoblock.write_model(AffineCamera.example((60, 80)), tmp_path / "m.json")
    result = run("project", model, points, "-o", readonly_dir / "out.csv")
    assert result.exit_code == 1
    assert f"--output '{readonly_dir / 'out.csv'}'" in result.output
    assert "read-only file system" in result.output and ".tmp" not in result.output


# ---------------------------------------------------------------------- the commands
def test_mosaic_with_out_last_loses_nothing(run, tmp_path):
    """The issue's case: 'geoblock mosaic before_left.tif before_right.tif out.tif', the
    gdalwarp habit, replaced before_left.tif with a mosaic when out.tif was left from an
    earlier run."""
    left = _ortho(tmp_path / "before_left.tif", 600000, 10)
    right = _ortho(tmp_path / "before_right.tif", 600005, 20)
    kept = left.read_bytes()
    out = tmp_path / "out.tif"
    # out.tif absent: the last ORTHO does not exist, so say OUT comes first
    result = run("mosaic", left, right, out)
    assert result.exit_code == 1
    assert "OUT first" in result.output and f"geoblock mosaic {out} {left} {right}" in result.output
    # out.tif left from an earlier run: OUT (before_left.tif) exists, refused
    shutil.copy(right, out)
    result = run("mosaic", left, right, out)
    assert result.exit_code == 1
    assert "exists; pass --overwrite" in result.output and "takes OUT first" in result.output
    assert left.read_bytes() == kept
    # OUT among the ORTHOs: refused even with --overwrite
    result = run("mosaic", left, left, right, "--overwrite")
    assert result.exit_code == 1 and "is also an input" in result.output
    assert left.read_bytes() == kept
    result = run("mosaic", tmp_path / "m.tif", left, right, "--contribution", tmp_path / "m.tif")
    assert result.exit_code == 1 and "also written as" in result.output
    # the right order works, and then needs --overwrite to run again
    result = run("mosaic", tmp_path / "m.tif", left, right, "--no-progress")
    assert result.exit_code == 0, result.output
    result = run("mosaic", tmp_path / "m.tif", left, right, "--no-progress")
    assert result.exit_code == 1 and "--overwrite" in result.output
    result = run("mosaic", tmp_path / "m.tif", left, right, "--no-progress", "--overwrite",
                 "--scheduler", "synchronous")
    assert result.exit_code == 0, result.output
    assert left.read_bytes() == kept


def test_point_outputs_are_not_clobbered(run, tmp_path):
    model = geoblock.write_model(AffineCamera.example((60, 80)), tmp_path / "m.json")
    points = tmp_path / "p.csv"
    points.write_text("lon,lat,h\n7.0,43.7,100\n")
    keep = tmp_path / "keep.csv"
    keep.write_text("precious\n")
    for command in ("project", "backproject"):
        result = run(command, model, points, "-o", keep)
        assert result.exit_code == 1 and "exists; pass --overwrite" in result.output
        assert keep.read_text() == "precious\n"
    result = run("project", model, points, "-o", points, "--overwrite")  # the input itself
    assert result.exit_code == 1 and "is also an input" in result.output
    assert points.read_text() == "lon,lat,h\n7.0,43.7,100\n"
    result = run("project", model, points, "-o", keep, "--overwrite")
    assert result.exit_code == 0, result.output
    assert keep.read_text().startswith("lon,lat,h,id,row,col,status")
    result = run("project", model, points, "-o", model, "--overwrite")
    assert result.exit_code == 1 and "MODEL" in result.output


def test_match_to_a_missing_directory_fails_before_matching(run, tmp_path):
    """'match -o nodir/tp.csv' did all the work, then failed naming a hidden temporary."""
    images = [_ortho(tmp_path / f"{k}.tif", 600000, 10) for k in "ab"]
    result = run("match", *images, "--dem", "const:0", "-o", tmp_path / "nodir" / "tp.csv")
    assert result.exit_code == 1
    assert f"--output '{tmp_path / 'nodir' / 'tp.csv'}'" in result.output
    assert "does not exist" in result.output and ".tmp" not in result.output
    assert "keypoints" not in result.output  # refused before any work


def test_ortho_refuses_an_existing_out_and_its_image(run, tmp_path):
    model = geoblock.write_model(AffineCamera.example((60, 80)), tmp_path / "m.json")
    image = tmp_path / "scene.tif"
    with open_quietly(image, "w", driver="GTiff", width=80, height=60, count=1,
                      dtype="uint8") as ds:
        ds.write(np.full((1, 60, 80), 7, np.uint8))
    kept = image.read_bytes()
    result = run("ortho", image, image, "--dem", "const:0", "--model", model, "--overwrite")
    assert result.exit_code == 1 and "is also an input (IMAGE" in result.output
    result = run("ortho", image, tmp_path / "o.tif", "--dem", "const:0", "--model", image)
    assert result.exit_code == 1  # the image is no model; nothing written
    out = tmp_path / "o.tif"
    out.write_bytes(b"mine")
    result = run("ortho", image, out, "--dem", "const:0", "--model", model)
    assert result.exit_code == 1 and "exists; pass --overwrite" in result.output
    assert out.read_bytes() == b"mine" and image.read_bytes() == kept


# ---------------------------------------------------------------------- ortho's new options
@pytest.fixture
def scene(tmp_path):
    model = AffineCamera.example((60, 80))
    path = geoblock.write_model(model, tmp_path / "m.json")
    image = tmp_path / "scene.tif"
    with open_quietly(image, "w", driver="GTiff", width=80, height=60, count=1,
                      dtype="uint8") as ds:
        ds.write(np.arange(60 * 80, dtype=np.uint32).reshape(1, 60, 80).astype(np.uint8) | 1)
    return image, path, model


def test_ortho_fill_height_is_gdals_missing_value(run, tmp_path, scene):
    """--fill-height H where the DEM has no height equals a DEM of constant H there."""
    image, model_path, _ = scene
    far = tmp_path / "far.tif"  # a DEM of another place
    with rasterio.open(far, "w", driver="GTiff", width=10, height=10, count=1, dtype="float32",
                       crs="EPSG:4979", transform=Affine(0.01, 0, 20, 0, -0.01, 10)) as ds:
        ds.write(np.zeros((1, 10, 10), np.float32))
    base = ["ortho", image, "--model", model_path, "--no-progress"]
    result = run(*base[:2], tmp_path / "void.tif", *base[2:], "--dem", far)
    assert result.exit_code == 1 and "--fill-height H" in result.output
    result = run(*base[:2], tmp_path / "filled.tif", *base[2:], "--dem", far,
                 "--fill-height", "120", "--dem-voids", "fill")
    assert result.exit_code == 0, result.output
    result = run(*base[:2], tmp_path / "const.tif", *base[2:], "--dem", "const:120")
    assert result.exit_code == 0, result.output
    with rasterio.open(tmp_path / "filled.tif") as a, rasterio.open(tmp_path / "const.tif") as b:
        assert a.transform == b.transform and a.shape == b.shape
        np.testing.assert_array_equal(a.read(), b.read())
    result = run(*base[:2], tmp_path / "x.tif", *base[2:], "--dem", far, "--fill-height", "nan")
    assert result.exit_code == 2 and "--fill-height" in result.output
    result = run(*base[:2], tmp_path / "x.tif", *base[2:], "--dem", far, "--dem-voids", "some")
    assert result.exit_code == 2 and "--dem-voids" in result.output


def test_ortho_warns_of_a_resolution_far_finer_than_the_gsd(run, tmp_path, scene):
    image, model_path, model = scene
    gsd = float(geoblock.ortho.OutputGrid.for_model(model, 0.0).resolution[0])
    base = ["ortho", image, "--model", model_path, "--dem", "const:0", "--no-progress"]
    result = run(*base[:2], tmp_path / "fine.tif", *base[2:], "--res", gsd / 20)
    assert result.exit_code == 0, result.output
    assert "Warning: --res" in result.stderr and "times finer than the image's" in result.stderr
    result = run(*base[:2], tmp_path / "ok.tif", *base[2:], "--res", gsd / 2)
    assert result.exit_code == 0 and "times finer" not in result.stderr


def test_scheduler_is_one_option(run, tmp_path, scene):
    image, model_path, _ = scene
    commands = build_cli()
    ctx = click.Context(commands)
    a = commands.get_command(ctx, "ortho")
    b = commands.get_command(ctx, "mosaic")
    [sa] = [p for p in a.params if p.name == "scheduler"]
    [sb] = [p for p in b.params if p.name == "scheduler"]
    assert (sa.metavar, sa.default, sa.help) == (sb.metavar, sb.default, sb.help)
    result = run("ortho", image, tmp_path / "s.tif", "--model", model_path, "--dem", "const:0",
                 "--no-progress", "--scheduler", "synchronous")
    assert result.exit_code == 0, result.output
    result = run("ortho", image, tmp_path / "t.tif", "--model", model_path, "--dem", "const:0",
                 "--no-progress", "--scheduler", "thread")
    assert result.exit_code == 2 and "--scheduler" in result.output
    assert not (tmp_path / "t.tif").exists()
