"""A full (or read-only) disk: every writer fails with one error naming the user's path, and the
previous file is left as it was, with no temporary beside it.

Each test mounts a small tmpfs, puts an old file there, fills the rest and writes something
larger. ``write_points`` used to open the target directly: on a full disk it destroyed the
old file and left the first rows of the new one; GDAL's errors named the hidden temporary.
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock.errors import GeoblockIOError
from geoblock.io import files, write_points
from geoblock.testing.synthetic import AffineCamera

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="tmpfs is Linux's")

OLD_CSV = b"id,lon,lat,h\n" + b"".join(b"%d,7.0,43.7,100.0\n" % i for i in range(300))


def _mount(folder: Path, *options: str) -> Path:
    """A 256 KiB tmpfs at ``folder``, or a skip saying why it cannot be mounted."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs to fill it needs root (CAP_SYS_ADMIN)")
    folder.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", ",".join(["size=256k", *options]),
                           "tmpfs", str(folder)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (a container without CAP_SYS_ADMIN?): "
                    f"{done.stderr.strip()}")
    return folder


@pytest.fixture
def disk(tmp_path, request):
    """An empty 256 KiB tmpfs, unmounted at the end."""
    folder = tmp_path / "disk"
    request.addfinalizer(lambda: subprocess.run(["umount", "-l", str(folder)], check=False))
    return _mount(folder)


def _fill(folder: Path) -> None:
    """Fill the file system of ``folder`` to the last byte."""
    with open(folder / "filler", "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"\0" * 4096)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC


def _check(disk: Path, info: pytest.ExceptionInfo, out: Path, old: bytes | None,
           plain: str = "no space left on device") -> None:
    """One error naming ``out`` (not a temporary) in plain words; ``out`` as it was; nothing
    else left on the disk."""
    message = str(info.value)
    assert len(message.splitlines()) == 1, message
    assert message.startswith("cannot write ") and str(out) in message, message
    assert f"{plain} ({disk})" in message, message
    assert ".tmp" not in message and "stage" not in message, message
    assert info.value.errno in (errno.ENOSPC, errno.EROFS)
    if old is None:
        assert not out.exists()
    else:
        assert out.read_bytes() == old
    expected = {"filler"} | ({out.name} if old is not None else set())
    assert {p.name for p in disk.iterdir()} == expected


def _points(n: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {"id": np.arange(n).astype(str), "lon": rng.random(n), "lat": rng.random(n),
            "h": 1000 * rng.random(n)}


def test_write_points_on_a_full_disk_keeps_the_old_file(disk):
    out = disk / "keep.csv"
    out.write_bytes(OLD_CSV)
    _fill(disk)
    with pytest.raises(GeoblockIOError) as info:
        write_points(out, _points(5000))
    _check(disk, info, out, OLD_CSV)
    assert "point file" in str(info.value)


def test_write_points_on_a_read_only_disk(tmp_path, request):
    folder = tmp_path / "ro"
    request.addfinalizer(lambda: subprocess.run(["umount", "-l", str(folder)], check=False))
    _mount(folder, "ro")
    with pytest.raises(GeoblockIOError) as info:
        write_points(folder / "tp.csv", _points(10))
    message = str(info.value)
    out = folder / "tp.csv"
    assert message == f"cannot write point file {out}: read-only file system ({folder})"
    assert info.value.errno == errno.EROFS


def test_model_json_on_a_full_disk_keeps_the_old_file(disk):
    out = disk / "model.json"
    old = geoblock.write_model(AffineCamera.example(), out).read_bytes()
    _fill(disk)
    big = {"model": "x", "schema_version": 1, "values": list(range(50_000))}
    with pytest.raises(GeoblockIOError) as info:
        files.write_json(out, big, "model JSON ")
    _check(disk, info, out, old)


@pytest.mark.parametrize("fmt", ["rpc-txt", "rpb", "gtiff"])
def test_rpc_export_on_a_full_disk_keeps_the_old_file(disk, fmt):
    pytest.importorskip("geoblock_rpc")
    from geoblock_rpc.model import RpcModel
    from geoblock_rpc.writers import WRITERS

    model = RpcModel.example()
    out = disk / {"rpc-txt": "scene_RPC.TXT", "rpb": "scene.RPB", "gtiff": "scene.tif"}[fmt]
    if fmt == "gtiff":
        WRITERS[fmt](model, out)  # updated in place, before: a copy now
    else:
        out.write_bytes(b"old\n" * 10)
    old = out.read_bytes()
    _fill(disk)
    with pytest.raises(GeoblockIOError) as info:
        WRITERS[fmt](model, out)
    _check(disk, info, out, old)


def _raster(path: Path, shape: tuple[int, int]) -> str:
    from geoblock.io.images import write_image

    data = (np.arange(shape[0] * shape[1]) % 251).astype(np.uint8).reshape(shape)
    return str(write_image(path, data, compress=None))


def test_write_ortho_on_a_full_disk_names_the_output(disk, tmp_path):
    from geoblock.io.dem import write_dem
    from geoblock.io.images import write_ortho
    from geoblock.ortho.mosaic import open_ortho

    source = write_dem(tmp_path / "a.tif", np.ones((300, 300)),
                       (0.001, 0.0, 7.0, 0.0, -0.001, 44.0), "EPSG:4326", "ellipsoid")
    data = open_ortho(str(source), chunks=64)
    out = disk / "ortho.tif"
    _fill(disk)
    with pytest.raises(GeoblockIOError) as info:
        write_ortho(data, out, compress=None, scheduler="synchronous")
    _check(disk, info, out, None)


def test_write_dem_on_a_full_disk_keeps_the_old_file(disk):
    from geoblock.io.dem import write_dem

    out = disk / "dem.tif"
    transform = (0.001, 0.0, 7.0, 0.0, -0.001, 44.0)
    write_dem(out, np.zeros((4, 4)), transform, "EPSG:4326", "ellipsoid")
    old = out.read_bytes()
    _fill(disk)
    with pytest.raises(GeoblockIOError) as info:
        write_dem(out, np.ones((300, 300)), transform, "EPSG:4326", "ellipsoid", compress=None)
    _check(disk, info, out, old)
    assert "DEM" in str(info.value)


def test_atomic_directory_on_a_full_disk_keeps_the_old_directory(disk):
    out = disk / "report"
    out.mkdir()
    (out / "report.md").write_text("old")
    _fill(disk)
    with pytest.raises(GeoblockIOError) as info:
        with files.atomic_directory(out, "report ", replaces=lambda p: True) as tmp:
            files.write_text(tmp / "report.md", "new " * 100_000)
    message = str(info.value)
    assert message == f"cannot write report {out}: no space left on device ({disk})"
    assert (out / "report.md").read_text() == "old"
    assert {p.name for p in disk.iterdir()} == {"filler", "report"}


def test_geoblock_ortho_on_a_full_disk_exits_1_with_one_error_line(disk, tmp_path):
    shape = (300, 300)
    model_path = geoblock.write_model(AffineCamera.example(shape), tmp_path / "model.json")
    image = _raster(tmp_path / "scene.tif", shape)
    out = disk / "ortho.tif"
    _fill(disk)
    exe = Path(sys.executable).with_name("geoblock")
    command = [str(exe)] if exe.exists() else [
        sys.executable, "-c", "import sys; from geoblock.cli.main import main; main()"]
    done = subprocess.run(
        command + ["ortho", image, str(out), "--dem", "const:150", "--model",
                   str(model_path), "--no-progress", "--compress", "none"],
        capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("Error:")]
    assert errors == [f"Error: cannot write {out}: no space left on device ({disk})"], done.stderr
    assert ".tmp" not in done.stderr
    assert {p.name for p in disk.iterdir()} == {"filler"}
