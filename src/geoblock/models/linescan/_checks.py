"""Argument checks and the interval search shared by the linescan building blocks (private
to :mod:`geoblock.models.linescan`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from geoblock.errors import ModelFormatError


def fail(where: str, message: str) -> ModelFormatError:
    """The error for a bad argument ``where`` (``"Ephemeris.time_s"``)."""
    return ModelFormatError(f"{where}: {message}")


def sample_array(value: Any, where: str, shape_tail: tuple[int, ...], min_len: int) -> np.ndarray:
    """A read-only float64 copy of ``value`` of shape ``(n, *shape_tail)``, finite, n >= min_len."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise fail(where, f"must be numeric ({exc})") from None
    if a.ndim != 1 + len(shape_tail) or a.shape[1:] != shape_tail:
        want = "(n" + "".join(f", {k}" for k in shape_tail) + ")"
        raise fail(where, f"must have shape {want}, got {a.shape}")
    if a.shape[0] < min_len:
        raise fail(where, f"needs at least {min_len} samples, got {a.shape[0]}")
    if not np.all(np.isfinite(a)):
        i = int(np.flatnonzero(~np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1))[0])
        raise fail(where, f"has non-finite values (sample {i})")
    a.flags.writeable = False
    return a


def check_increasing(t: np.ndarray, where: str) -> None:
    """Refuse sample times ``t`` (n,) that are not strictly increasing."""
    dt = np.diff(t)
    if np.any(~(dt > 0)):
        i = int(np.flatnonzero(~(dt > 0))[0])
        raise fail(where, f"must be strictly increasing (time_s[{i + 1}] = {t[i + 1]!r} <= "
                          f"time_s[{i}] = {t[i]!r})")


def segment(times: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interval index i (clipped to the end intervals), fraction s and its width, for times t."""
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, times.size - 2)
    width = times[i + 1] - times[i]
    return i, (t - times[i]) / width, width
