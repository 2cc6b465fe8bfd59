"""Atomic writes: every file geoblock writes appears complete under its name or not at all.

A file ``DIR/NAME`` is written under a hidden temporary ``DIR/.NAME.<12 hex digits>.tmp``
(``write_ortho``'s COG step uses a second one; ``.cog.tmp`` names of older runs are still
recognised as stale) and renamed to
``NAME`` only when complete. An exception, ``Ctrl-C`` or ``SIGTERM`` (the ``geoblock`` command
turns it into the same clean-up path, see :func:`geoblock.cli.main.main`) removes the temporary.
Only ``SIGKILL``, a crash of the interpreter or a power cut can leave one behind; the next write
of the same ``NAME`` removes such *stale* temporaries (:func:`remove_stale_temporaries`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

from geoblock.errors import GeoblockIOError

__all__ = ["atomic_directory", "atomic_path", "remove_stale_temporaries",
           "temporary_name_pattern", "write_error"]

#: A temporary not modified for this many seconds, and held open by no process of this host
#: that the user can inspect (``/proc``), is stale.
STALE_AFTER_S = 10.0
#: Where ``/proc`` cannot tell whether a process holds the file (macOS, Windows), a temporary
#: is stale only when it has not been modified for this many seconds.
STALE_AFTER_WITHOUT_PROC_S = 3600.0


#: The failures a user can act on, in plain words (``os.strerror`` gives the system's text, which
#: is also how GDAL reports them).
PLAIN_ERRORS = {
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
}


def _write_errors() -> tuple[type[BaseException], ...]:
    """What a failed write raises: ``OSError`` (rasterio's I/O errors are ones), and GDAL's own
    errors (``rasterio._err.CPLE_BaseError``) once rasterio is loaded (a writer through GDAL
    has imported it; this module does not)."""
    gdal = sys.modules.get("rasterio._err")
    base = getattr(gdal, "CPLE_BaseError", None)
    return (OSError,) if base is None else (OSError, base)


def _chain(exc: BaseException) -> list[BaseException]:
    """``exc`` and its causes and contexts, outermost first."""
    seen: list[BaseException] = []
    while exc is not None and not any(exc is e for e in seen):
        seen.append(exc)
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return seen


def _plain_errno(exc: BaseException, folder: Path) -> int | None:
    """The :data:`PLAIN_ERRORS` code behind ``exc``: an ``errno`` in its chain, else the
    system's text of one in a message (GDAL's: ``... failed: No space left on device``), else,
    for an error of GDAL's that says neither (``Write failed``), what ``folder``'s file system
    shows now, while the temporary still takes its space: full, read-only, not writable."""
    chain = _chain(exc)
    for e in chain:
        if isinstance(e, OSError) and e.errno in PLAIN_ERRORS:
            return e.errno
    for e in chain:
        for code in PLAIN_ERRORS:
            if os.strerror(code).lower() in str(e).lower():
                return code
    if isinstance(exc, OSError) and exc.errno is not None:
        return None  # the system said what it was: another failure
    try:
        fs = os.statvfs(folder)
    except (OSError, AttributeError):  # no statvfs on Windows
        return None
    if fs.f_flag & os.ST_RDONLY:
        return errno.EROFS
    if fs.f_bavail * fs.f_frsize < 1 << 20:  # less than 1 MiB: a full disk for GDAL's writes
        return errno.ENOSPC
    if not os.access(folder, os.W_OK):
        return errno.EACCES
    return None


def write_error(path: str | os.PathLike[str], exc: BaseException, what: str = "",
                temporary: str | os.PathLike[str] | None = None) -> GeoblockIOError:
    """The :class:`~geoblock.errors.GeoblockIOError` for a failure ``exc`` to write ``path``.

    One line that names ``path`` (the user's output), never the temporary it was written
    under. A full disk, an exceeded quota, a read-only file system or a folder the user may
    not write (``ENOSPC``, ``EDQUOT``, ``EROFS``, ``EACCES``) is said in plain words with the
    folder: ``cannot write tp.csv: no space left on device (/data/out)``; the exception's
    ``errno`` is then that code. Other failures keep the system's or GDAL's message.

    Parameters
    ----------
    path : str or path-like
        The final name of the file (or directory) being written.
    exc : BaseException
        The failure: an ``OSError`` (rasterio's I/O errors are ones) or GDAL's
        ``CPLE_BaseError``. GDAL's errors often say only ``Write failed``: then the folder's
        file system is looked at, so call this before the temporary is removed.
    what : str
        What is written (``"point file "``).
    temporary : str or path-like, optional
        The temporary the write went to: its name, and that of any temporary of ``path``
        (:func:`temporary_name_pattern`), is replaced by ``path``'s in the message.

    Returns
    -------
    GeoblockIOError
        To raise ``from exc``.
    """
    path = Path(path)
    folder = path.parent.absolute()
    mine = isinstance(exc, GeoblockIOError)  # geoblock's message: an input, an inner write
    code = exc.errno if isinstance(exc, GeoblockIOError) else _plain_errno(exc, folder)
    if code in PLAIN_ERRORS:
        error = GeoblockIOError(f"cannot write {what}{path}: {PLAIN_ERRORS[code]} ({folder})")
        error.errno = code
        return error
    if isinstance(exc, OSError) and exc.strerror and not mine:
        detail = exc.strerror  # without the file name, which may be the temporary
    else:
        detail = str(exc)
        if temporary is not None:
            detail = detail.replace(str(temporary), str(path))
            detail = detail.replace(Path(temporary).name, path.name)
        detail = temporary_name_pattern(path.name).sub(path.name, detail)  # a COG's second
    detail = " ".join(part.strip() for part in detail.splitlines() if part.strip())
    return GeoblockIOError(f"cannot write {what}{path}: {detail or type(exc).__name__}")


def temporary_name_pattern(name: str) -> re.Pattern[str]:
    """The names of geoblock's temporaries for the final file name ``name`` (and no other)."""
    return re.compile(rf"\.{re.escape(name)}\.[0-9a-f]{{12}}(?:\.cog)?\.tmp")


def _temporary_for(path: Path) -> Path:
    return path.parent / f".{path.name}.{uuid.uuid4().hex[:12]}.tmp"


def _open_files_on_this_host() -> set[tuple[int, int]] | None:
    """``(st_dev, st_ino)`` of every file open in a process of this host that this user can
    inspect (its own, ordinary processes: a geoblock run among them), or ``None`` without
    ``/proc``."""
    proc = Path("/proc")
    if not sys.platform.startswith("linux") or not (proc / "self" / "fd").is_dir():
        return None
    held: set[tuple[int, int]] = set()
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fds = list((entry / "fd").iterdir())
        except OSError:  # ended meanwhile, or another user's (or a non-dumpable) process
            continue
        for fd in fds:
            try:
                st = fd.stat()  # follows the link to the open file
            except OSError:
                continue
            held.add((st.st_dev, st.st_ino))
    return held


def remove_stale_temporaries(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporaries a killed earlier write of ``path`` left beside it.

    The rule, chosen so that a write in progress is never touched:

    * only files in ``path``'s folder named exactly ``.NAME.<12 hex digits>.tmp`` or
      ``.NAME.<12 hex digits>.cog.tmp``, with ``NAME`` the name of ``path`` (the temporaries of
      another output, or files a user named alike, are left alone), regular files (not
      symbolic links) owned by the current user;
    * and not modified for :data:`STALE_AFTER_S` seconds (10 s) *and* held open by no process
      of this host that the user can inspect (checked in ``/proc``, on Linux: the user's own
      processes, so any geoblock run writing it). Where ``/proc`` cannot tell, not modified
      for :data:`STALE_AFTER_WITHOUT_PROC_S` seconds (one hour).

    A write in progress holds its temporary open (GDAL, the JSON and CSV writers) or has just
    modified it (the instants between closing and renaming it), so it is never removed.

    A write of the same output by another host through a shared file system is not visible in
    ``/proc``: two concurrent writes of one output are not supported anyway (the last rename
    wins), and removing the other's temporary makes its write fail with an error naming the
    path rather than produce a wrong file.

    Parameters
    ----------
    path : str or path-like
        The final name of the file about to be written.

    Returns
    -------
    list of pathlib.Path
        The temporaries removed. Failures to remove one (permissions, a race) are ignored.
    """
    path = Path(path)
    pattern = temporary_name_pattern(path.name)
    try:
        candidates = [p for p in path.parent.iterdir() if pattern.fullmatch(p.name)]
    except OSError:
        return []
    if not candidates:
        return []
    now = time.time()
    uid = os.getuid() if hasattr(os, "getuid") else None
    old = []
    for candidate in candidates:
        try:
            st = candidate.lstat()
        except OSError:
            continue
        if not candidate.is_file() or candidate.is_symlink():
            continue
        if uid is not None and st.st_uid != uid:
            continue
        if now - st.st_mtime >= STALE_AFTER_S:
            old.append((candidate, st))
    if not old:
        return []
    held = _open_files_on_this_host()
    removed = []
    for candidate, st in old:
        if held is None:
            if now - st.st_mtime < STALE_AFTER_WITHOUT_PROC_S:
                continue
        elif (st.st_dev, st.st_ino) in held:
            continue
        try:
            candidate.unlink()
        except OSError:
            continue
        removed.append(candidate)
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], what: str = "") -> Iterator[Path]:
    """A temporary path beside ``path``, renamed to ``path`` when the block succeeds.

    A reader never sees a half-written file, and a failure (an exception, an interrupt,
    ``SIGTERM`` under the ``geoblock`` command) leaves any previous file intact and no
    temporary behind. Stale temporaries of the same ``path`` left by a killed earlier run
    are removed first (:func:`remove_stale_temporaries` gives the rule).

    Parameters
    ----------
    path : str or path-like
        The final name.
    what : str
        What is written, for the error message (``"block file "``).

    Raises
    ------
    GeoblockIOError
        The folder does not exist, or writing or renaming fails (an ``OSError``, which
        rasterio's I/O errors are, or GDAL's ``CPLE_BaseError``); the message names ``path``,
        never the temporary, in one line (:func:`write_error`: a full disk says so).
    """
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise GeoblockIOError(f"cannot write {what}{path}: the directory {folder} does not exist")
    remove_stale_temporaries(path)
    tmp = _temporary_for(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except _write_errors() as exc:
        raise write_error(path, exc, what, tmp) from exc
    finally:
        if os.path.lexists(tmp):  # not unlink(missing_ok): a read-only file system says EROFS
            tmp.unlink()


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike[str], what: str = "") -> Iterator[Path]:
    """A temporary directory beside ``path``, put in the place of ``path`` (a directory,
    replaced as a whole) when the block succeeds; on failure ``path`` stays as it was and the
    temporary is removed.

    Parameters
    ----------
    path : str or path-like
        The final directory (its parent is created if needed).
    what : str
        What is written, for the error message (``"adjustment output "``).

    Raises
    ------
    GeoblockIOError
        ``path`` exists and is not a directory, or writing or a rename fails (one line naming
        ``path``, never the temporary: :func:`write_error`).
    """
    import shutil
    import tempfile

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise GeoblockIOError(f"cannot write {what}{path}: it exists and is not a directory")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmpdir", dir=path.parent))
    except OSError as exc:
        raise write_error(path, exc, what) from exc
    try:
        yield tmp
        os.chmod(tmp, 0o755)
        if path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".old",
                                        dir=path.parent))
            os.replace(path, old / path.name)
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    except _write_errors() as exc:
        raise write_error(path, exc, what, tmp) from exc
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
