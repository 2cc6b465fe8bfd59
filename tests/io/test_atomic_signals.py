"""SIGTERM cleans up like Ctrl-C (exit codes 143 and 130), and stale temporaries of a killed run
are removed next time.

geoblock writes ``DIR/NAME`` under ``DIR/.NAME.<12 hex>.tmp`` and renames it when complete
(geoblock.io._atomic). ``SIGTERM`` (``timeout``, ``kill``, batch schedulers) used to kill the
``geoblock`` command on the spot and leave the temporary behind.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock.io import _atomic
from geoblock.io._atomic import atomic_path, remove_stale_temporaries, temporary_name_pattern

pytestmark = pytest.mark.skipif(
    sys.platform == "win32", reason="POSIX signals and /proc semantics"
)

# A ``geoblock`` command line with one plugin command that writes through atomic_path and
# sleeps in the middle of the write.
_SLOW_WRITER = textwrap.dedent(
    """
    import sys, time
    import click
    import geoblock.plugins as plugins
    from geoblock.hookspecs import hookimpl
    from geoblock.io._atomic import atomic_path
    from geoblock.cli.main import main

    class Slow:
        __name__ = "slow-writer"

        @hookimpl
        def geoblock_register_commands(self, cli):
            @cli.command(name="slow-write")
            @click.argument("out")
            def slow_write(out):
                with atomic_path(out) as tmp:
                    with open(tmp, "w") as f:
                        f.write("partial")
                    print("READY", flush=True)
                    time.sleep(120)

    pm = plugins.create_plugin_manager(entry_points=False, plugins=[Slow()])
    plugins.get_plugin_manager = lambda: pm
    main(sys.argv[1:])
    """
)


def _temporaries(folder: Path, name: str) -> list[Path]:
    pattern = temporary_name_pattern(name)
    return sorted(p for p in folder.iterdir() if pattern.fullmatch(p.name))


def _start_slow_write(out: Path) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-c", _SLOW_WRITER, "slow-write", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    line = proc.stdout.readline()
    if line.strip() != "READY":
        proc.kill()
        _, err = proc.communicate()
        pytest.fail(f"the slow writer did not start: {line!r} {err}")
    assert len(_temporaries(out.parent, out.name)) == 1  # mid-write: the temporary exists
    return proc


def test_sigterm_removes_the_temporary_and_exits_nonzero(tmp_path):
    out = tmp_path / "result.txt"
    proc = _start_slow_write(out)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "Aborted!" in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []  # neither the output nor a temporary


def test_sigint_cleans_up_and_exits_130(tmp_path):
    """Ctrl-C: 128 + SIGINT, as a shell reports it (click alone exits 1)."""
    out = tmp_path / "result.txt"
    proc = _start_slow_write(out)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGINT, err
    assert "Aborted!" in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


# A ``geoblock`` command line whose plugin command writes a point file with write_points; a
# column's value 50 000 rows in stops the write there (the rows before it are in the
# temporary), says READY and waits for the signal.
_POINT_WRITER = textwrap.dedent(
    """
    import sys, time
    import click
    import numpy as np
    import geoblock.plugins as plugins
    from geoblock.hookspecs import hookimpl
    from geoblock.io import write_points
    from geoblock.cli.main import main

    class Stop:
        def __str__(self):
            print("READY", flush=True)
            time.sleep(120)
            return "never"

    class Points:
        __name__ = "point-writer"

        @hookimpl
        def geoblock_register_commands(self, cli):
            @cli.command(name="write-points")
            @click.argument("out")
            def write(out):
                n = 100_000
                kind = np.full(n, "gcp", dtype=object)
                kind[50_000] = Stop()
                write_points(out, {"id": np.arange(n), "lon": np.linspace(7, 8, n),
                                   "lat": np.linspace(43, 44, n), "kind": kind})

    pm = plugins.create_plugin_manager(entry_points=False, plugins=[Points()])
    plugins.get_plugin_manager = lambda: pm
    main(sys.argv[1:])
    """
)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_in_the_middle_of_write_points_keeps_the_old_file(tmp_path, signum):
    out = tmp_path / "keep.csv"
    old = b"id,lon,lat\n1,7.0,43.0\n"
    out.write_bytes(old)
    proc = subprocess.Popen([sys.executable, "-c", _POINT_WRITER, "write-points", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    if line.strip() != "READY":
        proc.kill()
        _, err = proc.communicate()
        pytest.fail(f"the point writer did not start: {line!r} {err}")
    [tmp] = _temporaries(tmp_path, out.name)  # mid-write: 50 000 rows are in it
    assert tmp.stat().st_size > 0
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signum, err
    assert "Aborted!" in err and "Traceback" not in err
    assert out.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.csv"]


def test_stale_temporary_of_a_killed_run_is_removed_by_the_next_write(tmp_path, affine_camera):
    out = tmp_path / "model.json"
    proc = _start_slow_write(out)
    proc.kill()  # SIGKILL: nothing can clean up
    proc.communicate(timeout=60)
    [stale] = _temporaries(tmp_path, out.name)
    old = time.time() - 60
    os.utime(stale, (old, old))
    geoblock.write_model(affine_camera, out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]
    assert geoblock.open_model(out) == affine_camera


def test_the_stale_rule_spares_other_outputs_fresh_and_open_files(tmp_path):
    out = tmp_path / "dem.tif"
    old = time.time() - 3600

    def make(name, age=old):
        path = tmp_path / name
        path.write_bytes(b"x")
        os.utime(path, (age, age))
        return path

    stale = make(".dem.tif.0123456789ab.tmp")
    stale_cog = make(".dem.tif.ba9876543210.cog.tmp")
    other_output = make(".dem.tiff.0123456789ab.tmp")
    prefix_output = make(".x.dem.tif.0123456789ab.tmp")
    not_ours = make(".dem.tif.not-hex-name.tmp")
    fresh = make(".dem.tif.00000000000a.tmp", age=time.time())
    held = make(".dem.tif.00000000000b.tmp")
    with open(held, "rb"):
        removed = remove_stale_temporaries(out)
    assert sorted(removed) == sorted([stale, stale_cog])
    left = {p.name for p in tmp_path.iterdir()}
    assert left == {p.name for p in (other_output, prefix_output, not_ours, fresh, held)}


def test_without_proc_only_old_temporaries_are_stale(tmp_path, monkeypatch):
    monkeypatch.setattr(_atomic, "_open_files_on_this_host", lambda: None)
    out = tmp_path / "a.csv"
    minutes = tmp_path / ".a.csv.0123456789ab.tmp"
    hours = tmp_path / ".a.csv.ba9876543210.tmp"
    for path, age in ((minutes, 600), (hours, 2 * 3600)):
        path.write_text("x")
        t = time.time() - age
        os.utime(path, (t, t))
    assert remove_stale_temporaries(out) == [hours]
    assert minutes.exists()


def test_atomic_path_writes_and_leaves_only_the_file(tmp_path):
    out = tmp_path / "f.txt"
    with atomic_path(out) as tmp:
        assert temporary_name_pattern(out.name).fullmatch(tmp.name)
        tmp.write_text("done")
    assert out.read_text() == "done"
    assert list(tmp_path.iterdir()) == [out]


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_main_restores_the_previous_signal_handler(signum):
    from geoblock.cli.main import main

    def mine(signum, frame):  # pragma: no cover - never called
        pass

    previous = signal.signal(signum, mine)
    try:
        with pytest.raises(SystemExit) as info:
            main(["--version"])
        assert info.value.code == 0
        assert signal.getsignal(signum) is mine
    finally:
        signal.signal(signum, previous)


def _image(path, shape):
    import rasterio

    data = (np.arange(shape[0] * shape[1]) % 251).astype(np.uint8).reshape((1,) + shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(path, "w", driver="GTiff", width=shape[1], height=shape[0],
                           count=1, dtype="uint8") as ds:
            ds.write(data)
    return str(path)


def test_sigterm_during_geoblock_ortho_leaves_no_temporary(tmp_path):
    """The real command: a slow ortho (many small chunks) killed by SIGTERM mid-write."""
    from geoblock.testing.synthetic import AffineCamera

    shape = (3000, 3000)
    model = AffineCamera.example(shape)
    model_path = geoblock.write_model(model, tmp_path / "model.json")
    image = _image(tmp_path / "scene.tif", shape)
    out = tmp_path / "ortho.tif"
    geoblock_exe = Path(sys.executable).with_name("geoblock")
    command = [str(geoblock_exe)] if geoblock_exe.exists() else [
        sys.executable, "-c", "import sys; from geoblock.cli.main import main; main()"]
    proc = subprocess.Popen(
        command + ["ortho", image, str(out), "--dem", "const:150", "--model", str(model_path),
                   "--chunks", "32", "--no-progress", "--scheduler", "synchronous"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    deadline = time.monotonic() + 120
    while not _temporaries(tmp_path, out.name):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            _, err = proc.communicate()
            pytest.skip(f"the ortho ended before it could be interrupted: {err[-500:]}")
        time.sleep(0.05)
    time.sleep(0.5)
    if proc.poll() is not None:
        pytest.skip("the ortho ended before it could be interrupted")
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert not out.exists()
    assert _temporaries(tmp_path, out.name) == [], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json", "scene.tif"]
