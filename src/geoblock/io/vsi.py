"""GDAL virtual file systems (``/vsizip/``, ``/vsicurl/``, ``/vsis3/``, ``/vsimem/`` ...) for
files that are not rasters: sensor-model sidecars and metadata read inside an archive, on a
server or in memory, the way rasterio already reads the pixels.

A virtual path is kept as a string, never put through :mod:`pathlib` (which collapses the
``//`` of ``/vsicurl/https://host/x.tif`` and of ``/vsizip//abs/a.zip/x.tif``).
:func:`as_path` gives readers one object for either kind of path: a :class:`pathlib.Path` for
a local path, a :class:`VsiPath` for a virtual one. :class:`VsiPath` offers the part of
``Path``'s interface that metadata readers use (``name``, ``stem``, ``suffix``, ``parent``,
``/``, ``exists``, ``is_file``, ``is_dir``, ``iterdir``, ``glob``, ``read_bytes``), so a
reader that finds sidecars beside an image (``IMAGE_RPC.TXT``, ``IMAGE.RPB``, the
DigitalGlobe ``.IMD``/``.EPH``/``.ATT`` files) finds them inside an archive too.

The bytes are read by GDAL itself (``VSIFOpenL``/``VSIFReadL``/``VSIReadDir``), through the
GDAL library rasterio loaded, so that a virtual file is the same file for the pixels and for
the metadata (``/vsimem/`` files written with rasterio included) and GDAL's configuration
(``GDAL_HTTP_*``, ``AWS_*`` environment variables) applies to both. rasterio does not expose
these functions in Python, so they are called through :mod:`ctypes`.
"""

from __future__ import annotations

import ctypes
import fnmatch
import os
import posixpath
import threading
from collections.abc import Iterator
from pathlib import Path, PurePosixPath
from typing import Any

from geoblock.errors import GeoblockIOError

__all__ = ["VsiPath", "as_path", "exists", "is_vsi", "read_bytes"]

#: how a GDAL virtual path starts
PREFIX = "/vsi"


def is_vsi(path: object) -> bool:
    """Whether ``path`` is a GDAL virtual path (a string or path-like starting ``/vsi``)."""
    if isinstance(path, VsiPath):
        return True
    if not isinstance(path, str | os.PathLike):
        return False
    text = os.fspath(path)
    return isinstance(text, str) and text.startswith(PREFIX)


def as_path(path: str | os.PathLike[str]) -> Path | VsiPath:
    """A :class:`VsiPath` for a GDAL virtual path (kept as given), else a :class:`~pathlib.Path`.

    Readers call this instead of ``Path(path)``: a ``Path`` of ``/vsicurl/https://host/x``
    is ``/vsicurl/https:/host/x``, which names nothing.
    """
    if isinstance(path, VsiPath):
        return path
    if is_vsi(path):
        return VsiPath(os.fspath(path))
    return Path(path)


class VsiPath:
    """A GDAL virtual path, with the read-only part of :class:`pathlib.Path`'s interface.

    Parameters
    ----------
    path : str
        A path starting ``/vsi`` (``/vsizip/archive.zip/IMAGE.RPB``,
        ``/vsicurl/https://host/image.tif``...), kept exactly as given (a trailing ``/``
        dropped).

    Examples
    --------
    >>> p = VsiPath("/vsicurl/https://example.com/scene/IMAGE.TIF")
    >>> str(p.parent / "IMAGE.RPB")
    '/vsicurl/https://example.com/scene/IMAGE.RPB'
    >>> p.name, p.stem, p.suffix
    ('IMAGE.TIF', 'IMAGE', '.TIF')
    """

    __slots__ = ("_path",)

    def __init__(self, path: str) -> None:
        if not path.startswith(PREFIX):
            raise GeoblockIOError(f"{path!r} is not a GDAL virtual path (/vsi...)")
        stripped = path.rstrip("/")
        self._path = stripped if stripped.count("/") > 1 else path

    # ------------------------------------------------------------------ names
    def __fspath__(self) -> str:
        return self._path

    def __str__(self) -> str:
        return self._path

    def __repr__(self) -> str:
        return f"VsiPath({self._path!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, VsiPath) and other._path == self._path

    def __hash__(self) -> int:
        return hash(("VsiPath", self._path))

    def __lt__(self, other: VsiPath) -> bool:
        return self._path < other._path

    def __truediv__(self, name: str | os.PathLike[str]) -> VsiPath:
        return VsiPath(f"{self._path}/{os.fspath(name)}")

    @property
    def name(self) -> str:
        """The last component (``IMAGE.RPB``)."""
        return posixpath.basename(self._path)

    @property
    def suffix(self) -> str:
        """The last component's suffix (``.RPB``), as :attr:`pathlib.Path.suffix`."""
        return PurePosixPath(self.name).suffix

    @property
    def stem(self) -> str:
        """The last component without its suffix, as :attr:`pathlib.Path.stem`."""
        return PurePosixPath(self.name).stem

    @property
    def parent(self) -> VsiPath:
        """The folder holding this path (its ``//`` kept)."""
        return VsiPath(posixpath.dirname(self._path))

    def with_name(self, name: str) -> VsiPath:
        """This path with its last component replaced."""
        return self.parent / name

    def with_suffix(self, suffix: str) -> VsiPath:
        """This path with its suffix replaced."""
        return self.parent / (self.stem + suffix)

    def resolve(self) -> VsiPath:
        """Itself: a virtual path is already what GDAL opens."""
        return self

    # ------------------------------------------------------------------ file system
    def exists(self) -> bool:
        """Whether GDAL finds a file or folder there."""
        return self.is_file() or self.is_dir()

    def is_file(self) -> bool:
        """Whether GDAL can open a file there for reading."""
        lib = _gdal()
        handle = _open(lib, self._path)
        if not handle:
            return False
        lib.VSIFCloseL(handle)
        return not self.is_dir()

    def is_dir(self) -> bool:
        """Whether GDAL lists entries there (an empty folder counts as absent)."""
        return bool(_read_dir(self._path))

    def iterdir(self) -> Iterator[VsiPath]:
        """The entries of this folder."""
        for name in _read_dir(self._path):
            yield self / name

    def glob(self, pattern: str) -> Iterator[VsiPath]:
        """The entries of this folder whose name matches ``pattern`` (no ``/``, no ``**``)."""
        for entry in self.iterdir():
            if fnmatch.fnmatch(entry.name, pattern):
                yield entry

    def read_bytes(self) -> bytes:
        """All of the file (see :func:`read_bytes`)."""
        return read_bytes(self)


def exists(path: str | os.PathLike[str]) -> bool:
    """Whether a file or folder exists at ``path``, local or virtual."""
    return as_path(path).exists()


def read_bytes(path: str | os.PathLike[str], size: int | None = None, offset: int = 0) -> bytes:
    """All of a virtual file, or at most ``size`` bytes from ``offset``, read by GDAL.

    Raises
    ------
    GeoblockIOError
        GDAL cannot open the file (missing, unreachable); names the path as given.
    """
    text = os.fspath(path)
    if offset < 0 or (size is not None and size < 0):
        raise GeoblockIOError(f"{text!r}: cannot read: negative offset or size")
    lib = _gdal()
    handle = _open(lib, text)
    if not handle:
        raise GeoblockIOError(f"{text!r}: cannot read: GDAL cannot open it (no such file in "
                              "the archive, server or bucket, or it cannot be reached)")
    try:
        if size is None:
            lib.VSIFSeekL(handle, 0, 2)  # SEEK_END
            size = max(int(lib.VSIFTellL(handle)) - offset, 0)
        lib.VSIFSeekL(handle, offset, 0)
        buffer = ctypes.create_string_buffer(size)
        got = int(lib.VSIFReadL(buffer, 1, size, handle)) if size else 0
        return buffer.raw[:got]
    finally:
        lib.VSIFCloseL(handle)


# ---------------------------------------------------------------------------- GDAL's VSI API
_LOCK = threading.Lock()
_LIB: Any = None


class _Quiet:
    """GDAL's errors and warnings silenced on this thread (a missing file is an answer here;
    callers raise their own error naming the path)."""

    def __enter__(self) -> Any:
        lib = _gdal()
        lib.CPLPushErrorHandler(ctypes.cast(lib.CPLQuietErrorHandler, ctypes.c_void_p))
        return lib

    def __exit__(self, *exc: object) -> None:
        _gdal().CPLPopErrorHandler()


def _open(lib: Any, path: str) -> Any:
    with _Quiet():
        return lib.VSIFOpenL(path.encode(), b"rb")


def _read_dir(path: str) -> list[str]:
    lib = _gdal()
    with _Quiet():
        listing = lib.VSIReadDir(path.encode())
    if not listing:
        return []
    try:
        names = []
        k = 0
        while listing[k]:
            name = listing[k].decode("utf-8", "replace")
            if name not in (".", ".."):
                names.append(name)
            k += 1
        return sorted(names)
    finally:
        lib.CSLDestroy(listing)


def _gdal() -> Any:
    """The GDAL library rasterio loaded, with the VSI functions' signatures declared."""
    global _LIB
    with _LOCK:
        if _LIB is None:
            _LIB = _declare(_load())
        return _LIB


def _load() -> Any:
    import rasterio._io  # loads GDAL

    # the extension module's handle resolves symbols through its dependencies (ELF, Mach-O)
    lib = ctypes.CDLL(rasterio._io.__file__)
    if hasattr(lib, "VSIFOpenL"):
        return lib
    # Windows: GetProcAddress does not look in dependencies; load GDAL's DLL by its name
    import glob

    root = os.path.dirname(os.path.dirname(rasterio._io.__file__))
    for pattern in ("rasterio.libs/*gdal*", "rasterio/*gdal*.dll"):
        for candidate in sorted(glob.glob(os.path.join(root, pattern))):
            try:
                lib = ctypes.CDLL(candidate)
            except OSError:
                continue
            if hasattr(lib, "VSIFOpenL"):
                return lib
    raise GeoblockIOError("cannot read GDAL virtual files: the GDAL library rasterio uses "
                          "does not expose VSIFOpenL")


def _declare(lib: Any) -> Any:
    vp, sz, cp = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_char_p
    lib.VSIFOpenL.restype, lib.VSIFOpenL.argtypes = vp, [cp, cp]
    lib.VSIFCloseL.restype, lib.VSIFCloseL.argtypes = ctypes.c_int, [vp]
    lib.VSIFSeekL.restype, lib.VSIFSeekL.argtypes = ctypes.c_int, [vp, ctypes.c_uint64,
                                                                   ctypes.c_int]
    lib.VSIFTellL.restype, lib.VSIFTellL.argtypes = ctypes.c_uint64, [vp]
    lib.VSIFReadL.restype, lib.VSIFReadL.argtypes = sz, [vp, sz, sz, vp]
    lib.VSIReadDir.restype, lib.VSIReadDir.argtypes = ctypes.POINTER(cp), [cp]
    lib.CSLDestroy.restype, lib.CSLDestroy.argtypes = None, [ctypes.POINTER(cp)]
    lib.CPLPushErrorHandler.restype, lib.CPLPushErrorHandler.argtypes = None, [vp]
    lib.CPLPopErrorHandler.restype, lib.CPLPopErrorHandler.argtypes = None, []
    return lib
