"""Conformance checks for sensor models: what every :class:`~geoblock.models.SensorModel` must do.

Each ``check_*`` function takes any object following the SensorModel protocol (it does not
have to subclass :class:`~geoblock.models.SensorModelBase`), exercises one part of the contract
on a sample of points covering the whole image (pixel edges included) and the model's height
range (both ends), and raises an ``AssertionError`` whose message says which check failed, at
which point, what was expected, what the model gave, and the likely cause::

    check_round_trip failed for AffineCamera 'synthetic-affine': project(backproject(row, col, h))
    misses (row, col) by 0.5 px (tolerance 1e-06 px) at 75 of 100 points
      at:       row=-0.5, col=-0.5, h=-500 m
      expected: row=-0.5, col=-0.5
      got:      row=0, col=-0.5
      hint:     a half-pixel offset: ...

:func:`check_sensor_model` runs them all and reports every failed check at once;
:class:`geoblock.testing.contract.SensorModelContract` runs them one per pytest test.

The reference derivatives (:func:`numeric_partials_ground`, :func:`numeric_partials_parameters`)
are computed here, independently of the model's own (possibly inherited) partials.

Only numpy (and dask, for the token check) is needed; pytest is not imported.
"""

from __future__ import annotations

import inspect
import json
import math
import pickle
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from geoblock import coords
from geoblock.typing import ArrayLike, Status

__all__ = [
    "CHECKS",
    "check_dask_token",
    "check_footprint",
    "check_ground_partials",
    "check_metadata",
    "check_nan_isolation",
    "check_no_mutation",
    "check_parameter_partials",
    "check_parameter_perturbation",
    "check_parameter_sets",
    "check_partials",
    "check_pickle",
    "check_round_trip",
    "check_sensor_model",
    "check_serialization",
    "check_shapes",
    "check_with_parameters",
    "image_sample",
    "numeric_partials_ground",
    "numeric_partials_parameters",
    "parameter_steps",
]

_CONVERGED = int(Status.CONVERGED)
_INVALID = int(Status.INVALID_INPUT)
_NAME = re.compile(r"^[a-z][a-z0-9-]*$")
#: Precision assumed of a model's projection when differentiating it numerically, pixels.
_FD_NOISE_PX = 1e-9
#: Agreement required of two evaluations of the same points that should be identical.
_SAME_PX = 1e-9
_SAME_DEG = 1e-11
_SAME_M = 1e-6


# ================================================================================ messages
def _label(model: Any) -> str:
    return f"{type(model).__qualname__} {getattr(model, 'name', '<no name>')!r}"


def _error(
    check: str,
    model: Any,
    problem: str,
    *,
    at: str | None = None,
    expected: str | None = None,
    got: str | None = None,
    hint: str | None = None,
) -> AssertionError:
    """An ``AssertionError`` with a uniform, readable layout."""
    lines = [f"{check} failed for {_label(model)}: {problem}"]
    for key, value in (("at", at), ("expected", expected), ("got", got), ("hint", hint)):
        if value is not None:
            lines.append(f"  {key + ':':<9} {value}")
    return AssertionError("\n".join(lines))


def _g(x: Any) -> str:
    """A float for humans: 10 significant digits, ``nan`` as is."""
    try:
        return f"{float(x):.10g}"
    except (TypeError, ValueError):
        return repr(x)


def _at_image(row: Any, col: Any, h: Any) -> str:
    return f"row={_g(row)}, col={_g(col)}, h={_g(h)} m"


def _at_ground(lon: Any, lat: Any, h: Any) -> str:
    return f"lon={_g(lon)}, lat={_g(lat)}, h={_g(h)} m"


def _status_name(code: Any) -> str:
    try:
        return Status(int(code)).name
    except (ValueError, TypeError):
        return f"unknown status {code!r}"


def _call(
    check: str, model: Any, what: str, func: Callable[..., Any], *args: Any, **kw: Any
) -> Any:
    """Call a model method; turn any exception (or a warning turned error) into a check failure."""
    try:
        return func(*args, **kw)
    except Exception as exc:  # the model's exception is the finding
        raise _error(
            check,
            model,
            f"{what} raised {type(exc).__name__}: {exc}",
            hint="a conforming model handles this call for every point of the image (pixel "
            "edges included) and height range; per-point failures are NaN plus a status, never "
            "an exception (the original exception is chained)",
        ) from exc


# ================================================================================ sampling
def image_sample(
    model: Any, n: int = 5, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image points covering the whole image and height range, as used by the checks.

    A regular ``n x n`` grid from pixel edge to pixel edge (``-0.5 .. rows - 0.5`` and
    ``-0.5 .. cols - 0.5``) at the bottom, middle and top of ``height_range``, followed by
    ``n * n`` uniformly random points (``seed``).

    Parameters
    ----------
    model : SensorModel
    n : int
        Grid points per image side (>= 2).
    seed : int
        Seed of the random points.

    Returns
    -------
    row, col : ndarray, (4 n**2,)
        Pixels, pixel-centre convention.
    h : ndarray, (4 n**2,)
        Metres above the WGS84 ellipsoid.
    """
    if n < 2:
        raise ValueError(f"image_sample: n must be >= 2, got {n}")
    rows, cols = (int(v) for v in model.shape)
    h0, h1 = (float(v) for v in model.height_range)
    grid_r, grid_c, grid_h = np.meshgrid(
        np.linspace(-0.5, rows - 0.5, n),
        np.linspace(-0.5, cols - 0.5, n),
        np.array([h0, 0.5 * (h0 + h1), h1]),
        indexing="ij",
    )
    rng = np.random.default_rng(seed)
    m = n * n
    row = np.concatenate([grid_r.ravel(), rng.uniform(-0.5, rows - 0.5, m)])
    col = np.concatenate([grid_c.ravel(), rng.uniform(-0.5, cols - 0.5, m)])
    h = np.concatenate([grid_h.ravel(), rng.uniform(h0, h1, m)])
    return row, col, h


def _ground_sample(
    check: str, model: Any, row: np.ndarray, col: np.ndarray, h: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Backproject image points; every one must succeed (they are inside the image)."""
    (lon, lat, hh), status = _call(
        check, model, "backproject_with_status(row, col, h)", model.backproject_with_status,
        row, col, h,
    )
    lon, lat, hh, status = (np.asarray(a) for a in (lon, lat, hh, status))
    bad = (status != _CONVERGED) | ~(np.isfinite(lon) & np.isfinite(lat) & np.isfinite(hh))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise _error(
            check,
            model,
            f"backproject fails at {int(bad.sum())} of {bad.size} points inside the image and "
            "the height range",
            at=_at_image(row[i], col[i], h[i]),
            expected="status CONVERGED and finite lon, lat, h",
            got=f"status {_status_name(status[i])}, {_at_ground(lon[i], lat[i], hh[i])}",
            hint="the image covers [-0.5, rows - 0.5) x [-0.5, cols - 0.5) (pixel edges) at every "
            "height of height_range: check the validity domain and the convergence of "
            "iterative solvers there",
        )
    return lon, lat, hh


def _sample(model: Any, check: str, n: int, seed: int) -> tuple[np.ndarray, ...]:
    row, col, h = image_sample(model, n, seed)
    lon, lat, hh = _ground_sample(check, model, row, col, h)
    return row, col, h, lon, lat, hh


# ================================================================================ references
def parameter_steps(parameters: Any) -> np.ndarray:
    """Finite-difference steps of the parameter partials.

    ``1e-3 * sigma`` where the a-priori sigma is finite, else ``1e-6 * max(1, |value|)``.

    Parameters
    ----------
    parameters : ParameterSet
        ``values`` (P,) and ``sigmas`` (P,), in the parameters' units.

    Returns
    -------
    ndarray, (P,)
        Steps, in the parameters' units.
    """
    values = np.asarray(parameters.values, dtype=np.float64)
    sigmas = np.asarray(parameters.sigmas, dtype=np.float64)
    return np.where(np.isfinite(sigmas), 1e-3 * sigmas, 1e-6 * np.maximum(1.0, np.abs(values)))


def _project_flat(model: Any, lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    (r, c), _ = model.project_with_status(lon, lat, h)
    return np.stack([np.asarray(r, np.float64), np.asarray(c, np.float64)], axis=-1)


def numeric_partials_ground(
    model: Any, lon: Any, lat: Any, h: Any, *, step_m: float = 1.0
) -> np.ndarray:
    """Reference ground partials: central differences along local east, north and up.

    Each point is moved by ``+-step_m`` metres along its local ENU axes; the differences of
    ``model.project_with_status`` are chained to ECEF (``J_ecef = J_enu @ R``, ``R`` the
    ECEF -> ENU rotation at the point).

    Parameters
    ----------
    model : SensorModel
    lon, lat : array_like, (*S,)
        Degrees.
    h : array_like, (*S,)
        Metres above the WGS84 ellipsoid.
    step_m : float
        Step, metres.

    Returns
    -------
    ndarray, (*S, 2, 3)
        d(row, col)/d(x, y, z) ECEF, pixels per metre.
    """
    lon, lat, h = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (lon, lat, h)))
    shape = lon.shape
    rot = coords.enu_rotation(lon.ravel(), lat.ravel())  # (N, 3, 3) rows e, n, u in ECEF
    xyz = np.stack(coords.geodetic_to_ecef(lon.ravel(), lat.ravel(), h.ravel()), axis=-1)
    n = xyz.shape[0]
    axes = np.moveaxis(rot, 1, 0)  # (3, N, 3): ENU axis, point, ECEF component
    shifted = xyz[None, None] + step_m * np.array([1.0, -1.0])[:, None, None, None] * axes[None]
    g = coords.ecef_to_geodetic(shifted[..., 0], shifted[..., 1], shifted[..., 2])
    rc = _project_flat(model, g.lon.ravel(), g.lat.ravel(), g.h.ravel()).reshape(2, 3, n, 2)
    j_enu = np.moveaxis((rc[0] - rc[1]) / (2.0 * step_m), 0, -1)  # (N, 2, 3) d(r, c)/d(e, n, u)
    return (j_enu @ rot).reshape(shape + (2, 3))


def numeric_partials_parameters(
    model: Any, lon: Any, lat: Any, h: Any, *, steps: Any = None
) -> np.ndarray:
    """Reference parameter partials: central differences through ``with_parameters``.

    Parameters
    ----------
    model : SensorModel
    lon, lat : array_like, (*S,)
        Degrees.
    h : array_like, (*S,)
        Metres above the WGS84 ellipsoid.
    steps : array_like, (P,), optional
        Steps in the parameters' units; default :func:`parameter_steps`.

    Returns
    -------
    ndarray, (*S, 2, P)
        d(row, col)/d(parameter k), pixels per unit of parameter k.
    """
    lon, lat, h = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (lon, lat, h)))
    params = model.parameters
    values = np.array(params.values, dtype=np.float64)
    steps = parameter_steps(params) if steps is None else np.asarray(steps, dtype=np.float64)
    out = np.empty(lon.shape + (2, values.size))
    for k, step in enumerate(steps):
        sides = []
        for sign in (1.0, -1.0):
            v = values.copy()
            v[k] += sign * step
            sides.append(_project_flat(model.with_parameters(v), lon, lat, h))
        out[..., k] = (sides[0] - sides[1]) / (2.0 * step)
    return out


# ================================================================================ metadata
def check_metadata(model: Any) -> None:
    """Identity and extent of the model are sane.

    ``name`` is a lowercase-kebab string, ``schema_version`` an int >= 1, ``shape`` two
    ints > 0, ``height_range`` two finite floats with ``h_min < h_max``, and ``parameters``
    has P unique names, P finite float64 values, P sigmas > 0 and a (P,) boolean
    ``adjustable`` mask.

    Raises
    ------
    AssertionError
        Naming the offending attribute and its value.
    """
    check = "check_metadata"
    name = getattr(type(model), "name", None)
    if not isinstance(name, str) or not _NAME.match(name):
        raise _error(check, model, "the class attribute `name` is not a lowercase-kebab string",
                     expected=f"matching {_NAME.pattern}", got=repr(name),
                     hint="it is the registry key and the 'model' field of to_dict()")
    version = getattr(type(model), "schema_version", None)
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise _error(check, model, "the class attribute `schema_version` is not an int >= 1",
                     got=repr(version))
    shape = _call(check, model, "shape", lambda: model.shape)
    if (
        not isinstance(shape, tuple)
        or len(shape) != 2
        or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in shape)
        or not all(v > 0 for v in shape)
    ):
        raise _error(check, model, "`shape` is not a tuple of two ints > 0",
                     expected="(rows, cols)", got=repr(shape))
    hr = _call(check, model, "height_range", lambda: model.height_range)
    try:
        h0, h1 = (float(v) for v in hr)
        ok = math.isfinite(h0) and math.isfinite(h1) and h0 < h1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise _error(check, model, "`height_range` is not (h_min, h_max) finite with h_min < h_max",
                     got=repr(hr), hint="metres above the WGS84 ellipsoid")
    params = _call(check, model, "parameters", lambda: model.parameters)
    _check_parameter_set(check, model, params, "`parameters`")


def _check_parameter_set(check: str, model: Any, params: Any, what: str) -> None:
    """Raise a check failure unless ``params`` is a consistent ParameterSet."""
    try:
        names = tuple(params.names)
        values = np.asarray(params.values)
        sigmas = np.asarray(params.sigmas)
        adjustable = np.asarray(params.adjustable)
    except AttributeError as exc:
        raise _error(check, model, f"{what} is not a ParameterSet: {exc}",
                     got=repr(params)) from exc
    p = len(names)
    problems = []
    if len(set(names)) != p:
        problems.append(f"duplicate names {names}")
    if values.shape != (p,) or values.dtype != np.float64:
        problems.append(f"values of shape {values.shape} dtype {values.dtype} for {p} names")
    elif not np.all(np.isfinite(values)):
        problems.append(f"non-finite values {values.tolist()}")
    if sigmas.shape != (p,) or np.any(~(sigmas > 0)):
        problems.append(f"sigmas must be (P,) > 0 (inf when free), got {sigmas.tolist()}")
    if adjustable.shape != (p,) or adjustable.dtype != bool:
        problems.append(f"adjustable must be (P,) bool, got {adjustable!r}")
    if problems:
        raise _error(check, model, f"{what} is inconsistent: " + "; ".join(problems),
                     got=repr(params))


# ================================================================================ round trip
def _horizontal_jacobian(model: Any, lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(N, 2, 2) d(row, col)/d(east, north), pixels per metre, from the numeric reference."""
    j = numeric_partials_ground(model, lon, lat, h)
    j_enu = j @ np.swapaxes(coords.enu_rotation(lon, lat), -1, -2)  # d/d(e, n, u)
    return j_enu[..., :2]


def _round_trip_hint(d_row: float, d_col: float) -> str:
    miss = math.hypot(d_row, d_col)
    if not math.isfinite(miss):
        return ("the point is inside the image and the height range: project and backproject "
                "must both succeed there (check validity limits and iterative solvers)")
    for value in (abs(d_row), abs(d_col), miss, miss / math.sqrt(2.0)):
        if abs(value - 0.5) < 0.05:
            return ("a half-pixel offset: one direction uses the pixel-corner convention "
                    "(GDAL pixel/line, (0, 0) = corner of the first pixel) and the other the "
                    "pixel-centre convention geoblock uses ((0, 0) = centre of array[0, 0]); "
                    "convert corner coordinates with row = line - 0.5, col = pixel - 0.5")
    if miss < 0.01:
        return ("small but above tolerance: an iterative inversion stops too early; tighten "
                "its tolerance (SensorModelBase.newton_tolerance_px) or iteration cap")
    return ("project and backproject are not inverses: check they use the same state and "
            "parameters, the same (row, col) order and the same height (ellipsoidal, metres)")


def check_round_trip(model: Any, *, n: int = 5, seed: int = 0, tolerance_px: float = 1e-6) -> None:
    """``project`` and ``backproject`` are inverses, in both directions.

    Over :func:`image_sample` (pixel edges and both ends of ``height_range`` included):

    1. ``project(backproject(row, col, h))`` equals ``(row, col)`` to ``tolerance_px`` pixels
       and ``backproject`` returns the requested ``h``;
    2. for the ground points ``g`` so obtained, ``backproject(project(g), h)`` equals ``g`` to
       the ground distance that ``tolerance_px`` pixels represent there (the horizontal miss,
       in metres, is mapped to pixels through the numeric ground partials).

    Parameters
    ----------
    model : SensorModel
    n : int
        Grid points per image side (see :func:`image_sample`).
    seed : int
        Seed of the random points.
    tolerance_px : float
        Pixels.

    Raises
    ------
    AssertionError
        At the worst point, with expected and obtained coordinates and a hint (a miss of 0.5 px
        points at a pixel-corner/centre convention mismatch).
    """
    check = "check_round_trip"
    row, col, h, lon, lat, hh = _sample(model, check, n, seed)
    dh = np.abs(hh - h)
    if np.any(dh > _SAME_M):
        i = int(np.argmax(dh))
        raise _error(check, model, "backproject does not return the requested height",
                     at=_at_image(row[i], col[i], h[i]), expected=f"h={_g(h[i])} m",
                     got=f"h={_g(hh[i])} m",
                     hint="backproject(row, col, h) intersects the line of sight with the "
                     "surface at ellipsoidal height h and returns that h")
    (r2, c2), status = _call(check, model, "project_with_status(lon, lat, h)",
                             model.project_with_status, lon, lat, hh)
    r2, c2, status = np.asarray(r2), np.asarray(c2), np.asarray(status)
    miss = np.hypot(r2 - row, c2 - col)
    bad = ~(miss <= tolerance_px)
    if bad.any():
        i = int(np.argmax(np.where(np.isnan(miss), np.inf, miss)))
        extra = "" if status[i] == _CONVERGED else f" (status {_status_name(status[i])})"
        raise _error(
            check, model,
            f"project(backproject(row, col, h)) misses (row, col) by {_g(miss[i])} px (tolerance "
            f"{_g(tolerance_px)} px) at {int(bad.sum())} of {bad.size} points",
            at=_at_image(row[i], col[i], h[i]) + f" (ground {_at_ground(lon[i], lat[i], hh[i])})",
            expected=f"row={_g(row[i])}, col={_g(col[i])}",
            got=f"row={_g(r2[i])}, col={_g(c2[i])}{extra}",
            hint=_round_trip_hint(float(r2[i] - row[i]), float(c2[i] - col[i])),
        )
    # ground -> image -> ground
    (lon3, lat3, h3), status3 = _call(check, model, "backproject_with_status(row, col, h)",
                                      model.backproject_with_status, r2, c2, hh)
    lon3, lat3, h3 = np.asarray(lon3), np.asarray(lat3), np.asarray(h3)
    xyz = np.stack(coords.geodetic_to_ecef(lon, lat, hh), axis=-1)
    xyz3 = np.stack(coords.geodetic_to_ecef(lon3, lat3, h3), axis=-1)
    d_en = np.einsum("nij,nj->ni", coords.enu_rotation(lon, lat), xyz3 - xyz)[:, :2]
    jac = _horizontal_jacobian(model, lon, lat, hh)  # (N, 2, 2) px per metre
    miss_px = np.linalg.norm(np.einsum("nij,nj->ni", jac, d_en), axis=-1)
    miss_m = np.linalg.norm(d_en, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tol_m = tolerance_px / np.linalg.svd(jac, compute_uv=False)[:, -1]
    bad = ~(miss_px <= tolerance_px) | ~(np.abs(h3 - hh) <= _SAME_M)
    if bad.any():
        i = int(np.argmax(np.where(np.isnan(miss_px), np.inf, miss_px)))
        if not bad[i]:
            i = int(np.flatnonzero(bad)[0])
        raise _error(
            check, model,
            f"backproject(project(lon, lat, h)) misses the ground point by {_g(miss_m[i])} m, "
            f"i.e. {_g(miss_px[i])} px through the partials (tolerance {_g(tolerance_px)} px "
            f"= {_g(tol_m[i])} m there) at {int(bad.sum())} of {bad.size} points",
            at=_at_ground(lon[i], lat[i], hh[i]) + f" (image row={_g(r2[i])}, col={_g(c2[i])})",
            expected=_at_ground(lon[i], lat[i], hh[i]),
            got=_at_ground(lon3[i], lat3[i], h3[i])
            + ("" if status3[i] == _CONVERGED else f" (status {_status_name(status3[i])})"),
            hint="backproject does not invert project at this point: check both directions use "
            "the same state, and that backproject's iteration converges",
        )


# ================================================================================ partials
_GROUND_NAMES = ("x", "y", "z")
_IMAGE_NAMES = ("row", "col")


def _as_partials(
    check: str, model: Any, what: str, value: Any, shape: tuple[int, ...]
) -> np.ndarray:
    arr = np.asarray(value)
    if arr.shape != shape or arr.dtype != np.float64:
        raise _error(check, model, f"{what} has the wrong shape or dtype",
                     expected=f"shape {shape} float64", got=f"shape {arr.shape} {arr.dtype}",
                     hint="partials are (*S, 2, 3) d(row, col)/d(x, y, z) ECEF and "
                     "(*S, 2, P) d(row, col)/d(parameter), float64")
    return arr


def _pattern_hint(
    got: np.ndarray, ref: np.ndarray, candidates: Mapping[str, np.ndarray]
) -> str | None:
    scale = max(float(np.max(np.abs(ref))), 1e-300)
    for text, candidate in candidates.items():
        if candidate.shape == got.shape and np.max(np.abs(got - candidate)) <= 1e-3 * scale:
            return text
    return None


def check_ground_partials(
    model: Any, *, n: int = 5, seed: int = 0, rtol: float = 1e-4, step_m: float = 1.0
) -> None:
    """``partials_ground`` matches central differences in local ENU chained to ECEF.

    The reference is :func:`numeric_partials_ground` (computed here, independently of the
    model's own partials). Element ``[i, k, j]`` passes when ``|got - ref| <= rtol * s +
    noise``, ``s`` the largest magnitude of ``ref[i, k, :]`` (one output row at one point;
    at least 1 % of the largest partial overall) and ``noise`` the finite-difference noise of
    a projection good to 1e-9 px.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample (see :func:`image_sample`).
    rtol : float
        Relative tolerance.
    step_m : float
        Finite-difference step, metres.

    Raises
    ------
    AssertionError
        Naming the worst element (e.g. ``d row/d x``), the point, both values and, when
        recognised, the mistake (sign, row/col swap, ENU instead of ECEF).
    """
    check = "check_ground_partials"
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    got = _as_partials(check, model, "partials_ground(lon, lat, h)",
                       _call(check, model, "partials_ground(lon, lat, h)", model.partials_ground,
                             lon, lat, h), lon.shape + (2, 3))
    ref = numeric_partials_ground(model, lon, lat, h, step_m=step_m)
    if not np.all(np.isfinite(ref)):
        i = int(np.flatnonzero(~np.all(np.isfinite(ref), axis=(1, 2)))[0])
        raise _error(check, model, f"project fails within {_g(step_m)} m of a valid ground point, "
                     "so the partials cannot be checked", at=_at_ground(lon[i], lat[i], h[i]),
                     hint="project must work in a neighbourhood of the image and height range")
    scale = np.maximum(np.max(np.abs(ref), axis=-1, keepdims=True), 1e-2 * np.max(np.abs(ref)))
    tol = rtol * scale + _FD_NOISE_PX / step_m
    excess = np.abs(got - ref) / tol
    excess = np.where(np.isnan(excess), np.inf, excess)
    if np.any(excess > 1.0):
        i, k, j = (int(v) for v in np.unravel_index(int(np.argmax(excess)), excess.shape))
        rot = coords.enu_rotation(lon, lat)
        hint = _pattern_hint(got, ref, {
            "the sign is flipped": -ref,
            "the row and col partials are swapped": ref[..., ::-1, :],
            "these look like partials against local east/north/up: chain them to ECEF "
            "(J_ecef = J_enu @ coords.enu_rotation(lon, lat))": ref @ np.swapaxes(rot, -1, -2),
        }) or ("partials_ground must be d(row, col)/d(x, y, z) in ECEF metres (pixels per "
               "metre); compare with geoblock.testing.checks.numeric_partials_ground")
        n_bad = int(np.count_nonzero(np.any(excess > 1.0, axis=(1, 2))))
        raise _error(
            check, model,
            f"analytic d {_IMAGE_NAMES[k]}/d {_GROUND_NAMES[j]} differs from central "
            f"differences by {_g(abs(got[i, k, j] - ref[i, k, j]))} px/m (tolerance "
            f"{_g(tol[i, k, 0])} px/m) at {n_bad} of {lon.size} points",
            at=_at_ground(lon[i], lat[i], h[i]),
            expected=f"d {_IMAGE_NAMES[k]}/d (x, y, z) = {np.array2string(ref[i, k], precision=8)} "
            "(numeric)",
            got=f"d {_IMAGE_NAMES[k]}/d (x, y, z) = {np.array2string(got[i, k], precision=8)} "
            "(partials_ground)",
            hint=hint,
        )


def check_parameter_partials(model: Any, *, n: int = 5, seed: int = 0, rtol: float = 1e-4) -> None:
    """``partials_parameters`` matches central differences through ``with_parameters``.

    The reference is :func:`numeric_partials_parameters` with :func:`parameter_steps`. Column
    ``k`` passes when ``|got - ref| <= rtol * s_k + noise_k`` everywhere, ``s_k`` the largest
    magnitude of ``ref[..., k]`` and ``noise_k`` the difference noise of a projection good to
    1e-9 px over the step. Every parameter has a column, fixed ones included.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample (see :func:`image_sample`).
    rtol : float
        Relative tolerance.

    Raises
    ------
    AssertionError
        Naming the parameter and output (``d col/d roll``), the point, both values, and when
        recognised the mistake (sign, zero column, row/col swap, a constant factor such as
        degrees vs radians).
    """
    check = "check_parameter_partials"
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    params = model.parameters
    names = tuple(params.names)
    p = len(names)
    got = _as_partials(check, model, "partials_parameters(lon, lat, h)",
                       _call(check, model, "partials_parameters(lon, lat, h)",
                             model.partials_parameters, lon, lat, h), lon.shape + (2, p))
    if p == 0:
        return
    steps = parameter_steps(params)
    ref = _call(check, model, "with_parameters / project_with_status",
                numeric_partials_parameters, model, lon, lat, h, steps=steps)
    if not np.all(np.isfinite(ref)):
        i, _, k = np.unravel_index(int(np.flatnonzero(~np.isfinite(ref))[0]), ref.shape)
        raise _error(check, model, f"a model with parameter {names[k]!r} moved by "
                     f"{_g(steps[k])} fails to project a valid ground point",
                     at=_at_ground(lon[i], lat[i], h[i]))
    scale = np.max(np.abs(ref), axis=(0, 1))  # (P,)
    tol = rtol * scale + _FD_NOISE_PX / steps
    excess = np.abs(got - ref) / tol
    excess = np.where(np.isnan(excess), np.inf, excess)
    if np.any(excess > 1.0):
        i, r, k = np.unravel_index(int(np.argmax(excess)), excess.shape)
        g_k, r_k = got[..., k], ref[..., k]
        hint = _pattern_hint(g_k, r_k, {
            f"the sign of the {names[k]!r} column is flipped": -r_k,
            f"the {names[k]!r} column is zero": np.zeros_like(r_k),
            f"the row and col partials of {names[k]!r} are swapped": r_k[..., ::-1],
        })
        if hint is None:
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = float(np.sum(g_k * r_k) / np.sum(r_k * r_k))
            if np.max(np.abs(g_k - ratio * r_k)) <= 1e-3 * scale[k] and ratio != 0:
                hint = (f"the {names[k]!r} column is off by a constant factor {_g(ratio)}"
                        + (" (degrees vs radians?)" if abs(abs(ratio) - 180 / math.pi) < 0.01
                           or abs(abs(ratio) - math.pi / 180) < 1e-5 else "")
                        + f": partials are per unit of the parameter ({params.units[k]!r})")
            else:
                columns = [names[j] for j in range(p) if j != k
                           and np.max(np.abs(g_k - ref[..., j])) <= 1e-3 * max(scale[j], 1e-300)]
                hint = (f"the column looks like the one of {columns[0]!r}: columns follow "
                        "parameters.names" if columns else
                        "partials_parameters must be d(row, col)/d(parameter k) per unit of "
                        "the parameter, one column per parameter (fixed ones included)")
        n_bad = int(np.count_nonzero(np.any(excess > 1.0, axis=(1, 2))))
        raise _error(
            check, model,
            f"analytic d {_IMAGE_NAMES[r]}/d {names[k]} differs from central differences by "
            f"{_g(abs(got[i, r, k] - ref[i, r, k]))} px/{params.units[k]} (tolerance "
            f"{_g(tol[k])}) at {n_bad} of {lon.size} points",
            at=_at_ground(lon[i], lat[i], h[i]),
            expected=f"d {_IMAGE_NAMES[r]}/d {names[k]} = {_g(ref[i, r, k])} (numeric, step "
            f"{_g(steps[k])} {params.units[k]})",
            got=f"d {_IMAGE_NAMES[r]}/d {names[k]} = {_g(got[i, r, k])} (partials_parameters)",
            hint=hint,
        )


def check_partials(model: Any, *, n: int = 5, seed: int = 0, rtol: float = 1e-4) -> None:
    """Both :func:`check_ground_partials` and :func:`check_parameter_partials`.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample (see :func:`image_sample`).
    rtol : float
        Relative tolerance.
    """
    check_ground_partials(model, n=n, seed=seed, rtol=rtol)
    check_parameter_partials(model, n=n, seed=seed, rtol=rtol)


def check_parameter_perturbation(
    model: Any, *, n: int = 3, seed: int = 0, rtol: float = 0.1, motion_px: float = 1.0
) -> None:
    """Perturbing each adjustable parameter moves projections as the partials predict.

    For parameter ``k`` the step ``delta`` is scaled so that the larger of the actual and the
    predicted motion is about ``motion_px`` pixels; then ``project(with_parameters(v + delta
    e_k)) - project(model)`` must equal ``partials_parameters[..., k] * delta`` to ``rtol``
    of the motion. A wrong sign, a zero column or a wrong unit fails.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample (see :func:`image_sample`).
    rtol : float
        Relative tolerance on the motion.
    motion_px : float
        Target motion, pixels.

    Raises
    ------
    AssertionError
        Naming the parameter, the point, predicted vs actual motion.
    """
    check = "check_parameter_perturbation"
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    params = model.parameters
    names, values = tuple(params.names), np.array(params.values, dtype=np.float64)
    sigmas, adjustable = np.asarray(params.sigmas), np.asarray(params.adjustable, bool)
    base = _project_flat(model, lon, lat, h)
    pp = np.asarray(_call(check, model, "partials_parameters(lon, lat, h)",
                          model.partials_parameters, lon, lat, h))

    def motion(k: int, delta: float) -> np.ndarray:
        v = values.copy()
        v[k] += delta
        moved = _call(check, model, f"with_parameters (with {names[k]} + {_g(delta)})",
                      model.with_parameters, v)
        return _project_flat(moved, lon, lat, h) - base

    for k in np.flatnonzero(adjustable).tolist():
        delta = float(sigmas[k]) if np.isfinite(sigmas[k]) else 1e-3 * max(1.0, abs(values[k]))
        size = max(float(np.max(np.abs(motion(k, delta)))),
                   float(np.max(np.abs(pp[..., k]))) * delta)
        if not math.isfinite(size):
            raise _error(check, model, f"moving {names[k]!r} by {_g(delta)} {params.units[k]} "
                         "makes projections or partials non-finite")
        if size <= 1e3 * _FD_NOISE_PX:
            continue  # the parameter has no effect here, and the partials say so
        delta *= motion_px / size
        actual = motion(k, delta)
        predicted = pp[..., k] * delta
        err = np.linalg.norm(actual - predicted, axis=-1)
        allowed = rtol * float(np.max(np.linalg.norm(actual, axis=-1))) + 1e3 * _FD_NOISE_PX
        if np.any(~(err <= allowed)):
            i = int(np.argmax(np.where(np.isnan(err), np.inf, err)))
            dot = float(np.sum(actual * predicted))
            if not np.any(predicted):
                hint = (f"partials_parameters is zero for {names[k]!r} but the parameter "
                        "moves points")
            elif not np.any(actual):
                hint = (f"{names[k]!r} does not move points but its partials are not zero: "
                        "does with_parameters pass the value on?")
            elif dot < 0:
                hint = f"the partial of {names[k]!r} has the wrong sign"
            else:
                hint = (f"the partial of {names[k]!r} has the wrong size or direction; is it per "
                        f"unit of the parameter ({params.units[k]!r})?")
            raise _error(
                check, model,
                f"moving {names[k]!r} by {_g(delta)} {params.units[k]} moves the projection by "
                f"{_g(np.linalg.norm(actual[i]))} px, {_g(err[i])} px away from the "
                f"partials' prediction (allowed {_g(allowed)} px)",
                at=_at_ground(lon[i], lat[i], h[i]),
                expected=f"d(row, col) = ({_g(predicted[i, 0])}, {_g(predicted[i, 1])}) px "
                "(partials_parameters @ delta)",
                got=f"d(row, col) = ({_g(actual[i, 0])}, {_g(actual[i, 1])}) px (projection)",
                hint=hint,
            )


# ================================================================================ value semantics
def _json_problem(value: Any, path: str = "to_dict()") -> str | None:
    """Where a value is not plain JSON (dict/list/str/int/float/bool/None), or None."""
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                return f"{path} has a non-string key {key!r}"
            found = _json_problem(item, f"{path}[{key!r}]")
            if found:
                return found
        return None
    if isinstance(value, list):
        for j, item in enumerate(value):
            found = _json_problem(item, f"{path}[{j}]")
            if found:
                return found
        return None
    if isinstance(value, float):
        return None if math.isfinite(value) else f"{path} is {value!r} (JSON has no NaN/inf)"
    if value is None or type(value) in (str, int, bool):
        return None
    return (f"{path} is a {type(value).__module__}.{type(value).__qualname__} ({value!r:.60}); "
            "use plain float/int/str/bool/None, lists and dicts (e.g. array.tolist())")


def _same_projection(
    check: str, model: Any, other: Any, what: str, lon: np.ndarray, lat: np.ndarray, h: np.ndarray
) -> None:
    a = _project_flat(model, lon, lat, h)
    b = _call(check, model, f"{what}.project_with_status", _project_flat, other, lon, lat, h)
    diff = np.max(np.abs(a - b), axis=-1)
    bad = ~(diff <= 1e-12) & ~(np.isnan(a).all(-1) & np.isnan(b).all(-1))
    if bad.any():
        i = int(np.argmax(np.where(np.isnan(diff), np.inf, diff)))
        raise _error(check, model, f"{what} projects differently from the model "
                     f"({int(bad.sum())} of {bad.size} points)",
                     at=_at_ground(lon[i], lat[i], h[i]),
                     expected=f"row={_g(a[i, 0])}, col={_g(a[i, 1])}",
                     got=f"row={_g(b[i, 0])}, col={_g(b[i, 1])}",
                     hint="to_dict() must hold the whole state (every parameter value "
                     "included) and from_dict() must restore it")


def _equal(a: Any, b: Any) -> bool:
    result = a == b
    return bool(result) if isinstance(result, (bool, np.bool_)) else False


def check_serialization(model: Any, *, n: int = 3, seed: int = 0) -> None:
    """``to_dict``/``from_dict`` round trips, directly, through JSON text and the registry.

    ``to_dict()`` is JSON-safe (``json.dumps(..., allow_nan=False)`` of plain types), has
    ``"model" == model.name`` and ``"schema_version" == type(model).schema_version``;
    ``type(model).from_dict`` of it and of its JSON text gives an equal model with the same
    ``to_dict()`` that projects identically (<= 1e-12 px); when ``model.name`` is registered,
    ``geoblock.models.get_registry().from_dict`` does the same and maps to ``type(model)``.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample of the projection comparison (see :func:`image_sample`).

    Raises
    ------
    AssertionError
        Naming the offending key or the failing round trip.
    """
    check = "check_serialization"
    data = _call(check, model, "to_dict()", model.to_dict)
    if not isinstance(data, dict):
        raise _error(check, model, "to_dict() does not return a dict", got=type(data).__name__)
    problem = _json_problem(data)
    if problem:
        raise _error(check, model, "to_dict() is not JSON-safe", got=problem)
    try:
        text = json.dumps(data, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise _error(check, model, f"to_dict() is not JSON-safe: {exc}") from exc
    if data.get("model") != type(model).name:
        raise _error(check, model, "to_dict()['model'] is not the model's name",
                     expected=repr(type(model).name), got=repr(data.get("model")),
                     hint="the registry dispatches from_dict on this field")
    if data.get("schema_version") != type(model).schema_version:
        raise _error(check, model, "to_dict()['schema_version'] is not the class's schema_version",
                     expected=repr(type(model).schema_version),
                     got=repr(data.get("schema_version")))
    if not _equal(model, model):
        raise _error(check, model, "the model does not compare equal to itself",
                     hint="implement __eq__ (SensorModelBase compares canonical to_dict())")
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    rebuilt = {
        "type(model).from_dict(model.to_dict())": lambda: type(model).from_dict(model.to_dict()),
        "type(model).from_dict(json.loads(json.dumps(model.to_dict())))":
            lambda: type(model).from_dict(json.loads(text)),
    }
    from geoblock.models import get_registry

    registry = get_registry()
    if type(model).name in registry:
        registered = registry.get(type(model).name)
        if registered is not type(model):
            raise _error(check, model,
                         f"the name {type(model).name!r} is registered to another class",
                         expected=f"{type(model).__module__}.{type(model).__qualname__}",
                         got=f"{registered.__module__}.{registered.__qualname__}",
                         hint="give every model class its own `name`")
        rebuilt["geoblock.models.get_registry().from_dict(json.loads(text))"] = (
            lambda: registry.from_dict(json.loads(text)))
    for what, build in rebuilt.items():
        other = _call(check, model, what, build)
        if type(other) is not type(model):
            raise _error(check, model, f"{what} gives another type",
                         expected=type(model).__qualname__, got=type(other).__qualname__)
        other_text = json.dumps(_call(check, model, f"({what}).to_dict()", other.to_dict),
                                sort_keys=True, default=repr)
        if other_text != text:
            raise _error(check, model, f"{what} does not give back the same to_dict()",
                         expected=text[:400], got=other_text[:400],
                         hint="from_dict must restore every field that to_dict writes")
        if not _equal(other, model):
            raise _error(check, model, f"{what} is not == the model",
                         hint="equality must compare the state (SensorModelBase compares "
                         "canonical to_dict())")
        _same_projection(check, model, other, what, lon, lat, h)


def check_pickle(model: Any, *, n: int = 3, seed: int = 0) -> None:
    """``pickle`` round trip (highest protocol) gives an equal model that projects identically.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample of the projection comparison (see :func:`image_sample`).

    Raises
    ------
    AssertionError
    """
    check = "check_pickle"
    blob = _call(check, model, "pickle.dumps(model)", pickle.dumps, model, pickle.HIGHEST_PROTOCOL)
    other = _call(check, model, "pickle.loads(pickle.dumps(model))", pickle.loads, blob)
    if type(other) is not type(model) or not _equal(other, model):
        raise _error(check, model, "the unpickled model is not == the model",
                     got=repr(other), hint="pickle through to_dict()/from_dict() "
                     "(SensorModelBase.__reduce__) so that dask workers get the same model")
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    _same_projection(check, model, other, "pickle.loads(pickle.dumps(model))", lon, lat, h)


def check_partials_together(model: Any, *, n: int = 3, seed: int = 0) -> None:
    """``partials(lon, lat, h)``, when the model has it, equals ``(partials_ground,
    partials_parameters)`` called apart (the block adjustment uses it for both).

    Raises
    ------
    AssertionError
        Naming which of the two differs, and by how much.
    """
    check = "check_partials_together"
    both = getattr(model, "partials", None)
    if not callable(both):
        return  # optional: the adjustment then calls the two methods
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    got = _call(check, model, "partials(lon, lat, h)", both, lon, lat, h)
    if not (isinstance(got, tuple) and len(got) == 2):
        raise _error(check, model, "partials(lon, lat, h) must return a pair "
                     "(partials_ground, partials_parameters)")
    for name, value, ref in (("partials_ground", got[0], model.partials_ground(lon, lat, h)),
                             ("partials_parameters", got[1],
                              model.partials_parameters(lon, lat, h))):
        value, ref = np.asarray(value), np.asarray(ref)
        if value.shape != ref.shape or not np.allclose(value, ref, rtol=1e-12, atol=0.0,
                                                       equal_nan=True):
            worst = (float(np.nanmax(np.abs(value - ref))) if value.shape == ref.shape
                     else float("nan"))
            raise _error(check, model, f"partials(...) differs from {name}(...) (shapes "
                         f"{value.shape} and {ref.shape}, largest difference {_g(worst)})")


def check_dask_token(model: Any) -> None:
    """``dask.base.tokenize`` is deterministic and follows the model's value.

    The token is the same across calls and for an equal copy (``from_dict(to_dict())``), and
    differs for a model with any one parameter changed.

    Raises
    ------
    AssertionError
    """
    from dask.base import tokenize

    check = "check_dask_token"
    first = _call(check, model, "dask.base.tokenize(model)", tokenize, model)
    again = tokenize(model)
    if first != again:
        raise _error(check, model, "dask.base.tokenize(model) changes between calls",
                     got=f"{first} then {again}",
                     hint="define __dask_tokenize__ from the state (SensorModelBase uses "
                     "(name, canonical to_dict()))")
    copy = _call(check, model, "type(model).from_dict(model.to_dict())",
                 type(model).from_dict, model.to_dict())
    if tokenize(copy) != first:
        raise _error(check, model, "an equal copy (from_dict(to_dict())) has another dask token",
                     hint="the token must depend on the value only (no id(), no uuid)")
    params = model.parameters
    values, steps = np.array(params.values, dtype=np.float64), parameter_steps(params)
    for k, name in enumerate(params.names):
        v = values.copy()
        v[k] += steps[k]
        changed = _call(check, model, f"with_parameters (with {name} changed)",
                        model.with_parameters, v)
        if tokenize(changed) == first:
            raise _error(check, model, f"a model with changed parameters ({name!r} + "
                         f"{_g(steps[k])}) has the same dask token",
                         hint="the token must include every parameter value (and to_dict() "
                         f"must hold {name!r})")


def check_with_parameters(model: Any, *, n: int = 3, seed: int = 0) -> None:
    """``with_parameters`` builds new models and never mutates.

    * ``with_parameters(parameters.values)`` is == the model and projects identically;
    * changing any one parameter gives a model that is != the model, holds the new values
      and the same names, units, sigmas and adjustable mask, while the model itself (its
      ``to_dict()`` and parameter values) is unchanged;
    * values of the wrong length are refused (an exception).

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample of the projection comparison (see :func:`image_sample`).

    Raises
    ------
    AssertionError
    """
    check = "check_with_parameters"
    params = model.parameters
    names = tuple(params.names)
    values = np.array(params.values, dtype=np.float64)
    before = _snapshot(model)

    def same_metadata(new: Any, what: str) -> None:
        for attr in ("names", "units", "sigmas", "adjustable", "covariance"):
            a, b = getattr(params, attr, None), getattr(new.parameters, attr, None)
            if not np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object)):
                raise _error(check, model, f"{what} changes parameters.{attr}",
                             expected=repr(a), got=repr(b),
                             hint="only the values change; keep names, units, sigmas, "
                             "adjustable and covariance")

    same = _call(check, model, "with_parameters(parameters.values)", model.with_parameters, values)
    if type(same) is not type(model):
        raise _error(check, model, "with_parameters returns another type",
                     expected=type(model).__qualname__, got=type(same).__qualname__)
    same_metadata(same, "with_parameters(parameters.values)")
    if not _equal(same, model):
        raise _error(check, model, "with_parameters(parameters.values) is not == the model",
                     got=_diff_keys(before, _snapshot(same)) or repr(same),
                     hint="with_parameters must keep every other piece of state")
    _, _, _, lon, lat, h = _sample(model, check, n, seed)
    _same_projection(check, model, same, "with_parameters(parameters.values)", lon, lat, h)
    steps = parameter_steps(params)
    for k, name in enumerate(names):
        v = values.copy()
        v[k] += steps[k]
        other = _call(check, model, f"with_parameters (with {name} changed)",
                      model.with_parameters, v)
        new = other.parameters
        if not np.array_equal(np.asarray(new.values), v):
            raise _error(check, model, f"with_parameters does not set {name!r}",
                         expected=repr(v.tolist()), got=repr(np.asarray(new.values).tolist()))
        same_metadata(other, f"with_parameters (with {name} changed)")
        if _equal(other, model):
            raise _error(check, model, f"a model with {name!r} changed by {_g(steps[k])} is == the "
                         "original", hint=f"to_dict() (which equality, pickling and dask tokens "
                         f"use) probably does not record {name!r}")
        if _snapshot(model) != before or not np.array_equal(np.asarray(params.values), values):
            raise _error(check, model, f"with_parameters (with {name} changed) mutates the model",
                         hint="models are immutable: build a new one")
    try:
        model.with_parameters(np.append(values, 0.0))
    except Exception:  # any refusal is fine
        pass
    else:
        raise _error(check, model, f"with_parameters accepts {len(values) + 1} values for "
                     f"{len(values)} parameters", hint="refuse values whose shape is not (P,) "
                     "(ParameterSet.with_values does)")


_UNKNOWN_SET = "no-such-parameter-set"
_UNKNOWN_OPTION = "no_such_option"


def check_parameter_sets(
    model: Any,
    *,
    parameter_set_options: Mapping[str, Mapping[str, Any]] | None = None,
    tolerance_px: float = 1e-6,
) -> dict[str, str]:
    """Named parameter presets: ``parameter_sets`` and ``with_parameter_set(name, **options)``.

    * ``parameter_sets`` is a tuple of unique names with ``"default"`` among them, the same
      on every access;
    * ``with_parameter_set("default")`` is == the model, with the same parameters;
    * for every listed name, ``with_parameter_set(name, **parameter_set_options.get(name,
      {}))`` returns a model of the same type and shape whose ``parameters`` is a consistent
      ParameterSet, which projects and backprojects the image centre (middle of the height
      range) consistently, whose ``with_parameter_set("default")`` is == itself and which
      ``from_dict(to_dict())`` (through JSON text) gives back with the same parameters; the
      model is not changed;
    * an unknown name and an unknown option raise
      :class:`~geoblock.errors.ParameterSetError`; the unknown name's message names it and
      the known sets.

    A set that raises ``ParameterSetError`` when called without options (one that needs an
    option, such as ``"dg"``'s ``accuracy_m`` on a model that does not know its location
    accuracy) is not checked: it is returned with the error's message. Give it options
    through ``parameter_set_options`` to check it.

    Parameters
    ----------
    model : SensorModel
    parameter_set_options : mapping of str to mapping, optional
        Options per set name, e.g. ``{"dg": {"accuracy_m": 10.0}}`` (names the model does not
        list are ignored).
    tolerance_px : float
        Round-trip tolerance at the image centre, pixels.

    Returns
    -------
    dict of str to str
        The sets not checked, with the reason.

    Raises
    ------
    AssertionError
    """
    from geoblock.errors import ParameterSetError

    check = "check_parameter_sets"
    options = dict(parameter_set_options or {})
    before = _snapshot(model)
    for member in ("parameter_sets", "with_parameter_set"):
        if not hasattr(type(model), member):
            raise _error(check, model, f"the model has no `{member}`",
                         hint="the SensorModel protocol requires `parameter_sets` (the names of "
                         "the parameter presets, at least ('default',)) and "
                         "`with_parameter_set(name, **options)`; SensorModelBase provides both")
    sets = _call(check, model, "parameter_sets", lambda: model.parameter_sets)
    hint_sets = ("parameter_sets lists the presets' names (a tuple of str, 'default' first: "
                 "SensorModelBase's default is ('default',))")
    if (not isinstance(sets, tuple) or not all(isinstance(n, str) and n for n in sets)
            or len(set(sets)) != len(sets) or "default" not in sets):
        raise _error(check, model, "parameter_sets is not a tuple of unique names with "
                     "'default' among them", got=repr(sets), hint=hint_sets)
    if model.parameter_sets != sets:
        raise _error(check, model, "parameter_sets changes between accesses",
                     got=f"{sets!r} then {model.parameter_sets!r}", hint=hint_sets)
    rows, cols = model.shape
    centre = ((rows - 1) / 2.0, (cols - 1) / 2.0)
    h_mid = 0.5 * (float(model.height_range[0]) + float(model.height_range[1]))
    skipped: dict[str, str] = {}
    for name in sets:
        opts = dict(options.get(name, {}))
        call = f"with_parameter_set({name!r}" + "".join(
            f", {k}={v!r}" for k, v in opts.items()) + ")"
        try:
            preset = model.with_parameter_set(name, **opts)
        except ParameterSetError as exc:
            if opts or name == "default":
                raise _error(check, model, f"{call} raised ParameterSetError: {exc}",
                             hint="every name in parameter_sets must be accepted (with the "
                             "options given); 'default' needs none") from exc
            skipped[name] = str(exc)
            continue
        except Exception as exc:
            raise _error(check, model, f"{call} raised {type(exc).__name__}: {exc}",
                         hint="a set that cannot be built raises ParameterSetError saying "
                         "why (the original exception is chained)") from exc
        if type(preset) is not type(model):
            raise _error(check, model, f"{call} returns another type",
                         expected=type(model).__qualname__, got=type(preset).__qualname__)
        if tuple(preset.shape) != tuple(model.shape):
            raise _error(check, model, f"{call} changes the shape",
                         expected=repr(model.shape), got=repr(preset.shape))
        _check_parameter_set(check, model, preset.parameters, f"{call}.parameters")
        if name == "default" and not (
            _equal(preset, model) and _equal(preset.parameters, model.parameters)
        ):
            raise _error(check, model, f"{call} is not the model as it is",
                         expected=repr(model.parameters), got=repr(preset.parameters),
                         hint="'default' means the parameters as the model has them now "
                         "(SensorModelBase returns self)")
        (g_lon, g_lat, g_h), st_b = _call(check, model, f"{call}.backproject_with_status",
                                          preset.backproject_with_status,
                                          centre[0], centre[1], h_mid)
        (row, col), st_p = _call(check, model, f"{call}.project_with_status",
                                 preset.project_with_status, g_lon, g_lat, h_mid)
        miss = math.hypot(float(row) - centre[0], float(col) - centre[1])
        if int(st_b) != _CONVERGED or int(st_p) != _CONVERGED or not miss <= tolerance_px:
            raise _error(check, model, f"{call} does not project the image centre",
                         at=_at_image(centre[0], centre[1], h_mid),
                         expected=f"row={_g(centre[0])}, col={_g(centre[1])} (CONVERGED)",
                         got=f"row={_g(row)}, col={_g(col)} (backproject "
                         f"{_status_name(st_b)}, project {_status_name(st_p)})",
                         hint="a preset chooses which parameters an adjustment estimates; the "
                         "model it returns must still work")
        back = _call(check, model, f"{call}.with_parameter_set('default')",
                     preset.with_parameter_set, "default")
        if not _equal(back, preset):
            raise _error(check, model, f"{call}.with_parameter_set('default') is not == "
                         "itself", hint="'default' means the parameters as they are")
        if name != "default":  # the model's own round trip is check_serialization's
            text = _call(check, model, f"{call}.to_dict()",
                         lambda p=preset: json.dumps(p.to_dict(), allow_nan=False))
            again = _call(check, model, f"from_dict({call}.to_dict())",
                          type(preset).from_dict, json.loads(text))
            if not (_equal(again, preset)
                    and _equal(again.parameters, preset.parameters)):
                raise _error(check, model, f"from_dict({call}.to_dict()) does not give the "
                             "preset back", expected=repr(preset.parameters),
                             got=repr(again.parameters),
                             hint="to_dict() must record the preset's parameters (names, "
                             "values, sigmas, adjustable mask) and from_dict() restore them")
        if _snapshot(model) != before:
            raise _error(check, model, f"{call} mutates the model",
                         got=_diff_keys(before, _snapshot(model)),
                         hint="models are immutable: build a new one")
    try:
        model.with_parameter_set(_UNKNOWN_SET)
    except ParameterSetError as exc:
        missing = [n for n in (_UNKNOWN_SET, *sets) if n not in str(exc)]
        if missing:
            raise _error(check, model, f"the ParameterSetError for an unknown set does not name "
                         f"{missing}", got=str(exc), hint="name the set asked for and the "
                         "known ones (SensorModelBase does)") from exc
    except Exception as exc:
        raise _error(check, model, f"with_parameter_set({_UNKNOWN_SET!r}) raised "
                     f"{type(exc).__name__}, not ParameterSetError: {exc}",
                     hint="raise geoblock.errors.ParameterSetError") from exc
    else:
        raise _error(check, model, f"with_parameter_set({_UNKNOWN_SET!r}) does not raise",
                     hint="refuse names not in parameter_sets with ParameterSetError")
    try:
        model.with_parameter_set("default", **{_UNKNOWN_OPTION: 1.0})
    except ParameterSetError as exc:
        if _UNKNOWN_OPTION not in str(exc):
            raise _error(check, model, "the ParameterSetError for an unknown option does not "
                         "name it", got=str(exc)) from exc
    except Exception as exc:
        raise _error(check, model, f"with_parameter_set('default', {_UNKNOWN_OPTION}=1.0) "
                     f"raised {type(exc).__name__}, not ParameterSetError: {exc}",
                     hint="raise geoblock.errors.ParameterSetError") from exc
    else:
        raise _error(check, model, f"with_parameter_set('default', {_UNKNOWN_OPTION}=1.0) "
                     "does not raise", hint="refuse unknown options with ParameterSetError "
                     "naming them (SensorModelBase._parameter_set_request does)")
    return skipped


def _snapshot(model: Any) -> str:
    return json.dumps(model.to_dict(), sort_keys=True, default=repr)


def _diff_keys(before: str, after: str) -> str:
    try:
        a, b = json.loads(before), json.loads(after)
    except ValueError:
        return ""
    keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    return "; ".join(
        f"{k!r}: {json.dumps(a.get(k))[:80]} -> {json.dumps(b.get(k))[:80]}" for k in keys
    )


def _scramble(value: Any) -> None:
    """Mutate every dict and list inside ``value`` in place."""
    if isinstance(value, dict):
        for item in value.values():
            _scramble(item)
        value["__scrambled__"] = True
    elif isinstance(value, list):
        for item in value:
            _scramble(item)
        for j, item in enumerate(value):
            if isinstance(item, (int, float)) and not isinstance(item, bool):
                value[j] = item + 1
        value.append(None)


def check_no_mutation(model: Any, *, n: int = 3, seed: int = 0) -> None:
    """No method changes the model or its input arrays.

    ``to_dict()`` (canonical JSON) and the parameter values are compared before and after each
    of ``project``, ``backproject``, ``*_with_status``, ``partials_ground``,
    ``partials_parameters``, ``with_parameters``, ``to_dict``/``from_dict``, pickling,
    ``repr`` and, when present, ``footprint`` and ``los``; the input arrays must be left as
    they were; editing the dictionary ``to_dict()`` returned must not change the model.

    Parameters
    ----------
    model : SensorModel
    n, seed : int
        Sample (see :func:`image_sample`).

    Raises
    ------
    AssertionError
        Naming the method and the changed ``to_dict()`` keys.
    """
    check = "check_no_mutation"
    row, col, h, lon, lat, hh = _sample(model, check, n, seed)
    values = np.array(model.parameters.values, dtype=np.float64)
    steps = parameter_steps(model.parameters)
    calls: list[tuple[str, Callable[[], Any], tuple[np.ndarray, ...]]] = [
        ("project(lon, lat, h)", lambda: model.project(lon, lat, hh), (lon, lat, hh)),
        ("backproject(row, col, h)", lambda: model.backproject(row, col, h), (row, col, h)),
        ("project_with_status(lon, lat, h)", lambda: model.project_with_status(lon, lat, hh),
         (lon, lat, hh)),
        ("backproject_with_status(row, col, h)",
         lambda: model.backproject_with_status(row, col, h), (row, col, h)),
        ("partials_ground(lon, lat, h)", lambda: model.partials_ground(lon, lat, hh),
         (lon, lat, hh)),
        ("partials_parameters(lon, lat, h)", lambda: model.partials_parameters(lon, lat, hh),
         (lon, lat, hh)),
        ("with_parameters(values + step)", lambda: model.with_parameters(values + steps), ()),
        ("with_parameters(values)", lambda: model.with_parameters(values), ()),
        ("from_dict(to_dict())", lambda: type(model).from_dict(model.to_dict()), ()),
        ("pickle.dumps(model)", lambda: pickle.dumps(model), ()),
        ("repr(model)", lambda: repr(model), ()),
    ]
    if callable(getattr(model, "footprint", None)):
        calls.append(("footprint()", lambda: model.footprint(), ()))
    if callable(getattr(model, "los", None)):
        calls.append(("los(row, col)", lambda: model.los(row, col), (row, col)))
    before = _snapshot(model)
    for what, call, inputs in calls:
        saved = [a.copy() for a in inputs]
        _call(check, model, what, call)
        after = _snapshot(model)
        if after != before or not np.array_equal(np.asarray(model.parameters.values), values):
            raise _error(check, model, f"calling {what} changed the model",
                         got=_diff_keys(before, after) or "parameters.values changed",
                         hint="models are immutable values (equality, pickling and dask tokens "
                         "rely on it): keep caches out of to_dict() and never assign to the "
                         "model's state after __init__")
        for name, a, b in zip(("first", "second", "third"), saved, inputs, strict=False):
            if not np.array_equal(a, b, equal_nan=True):
                raise _error(check, model, f"calling {what} modified its {name} input array",
                             hint="never write into the caller's arrays (no in-place "
                             "operations on inputs; copy first)")
    data = model.to_dict()
    _scramble(data)
    if _snapshot(model) != before:
        raise _error(check, model, "editing the dictionary returned by to_dict() changed the model",
                     got=_diff_keys(before, _snapshot(model)),
                     hint="to_dict() returns internal lists/dicts: return fresh copies")


# ================================================================================ NaN, shapes
def _nan_sample(model: Any, check: str) -> tuple[np.ndarray, ...]:
    rows, cols = model.shape
    h0, h1 = model.height_range
    r, c = np.meshgrid(np.linspace(0.0, rows - 1.0, 3), np.linspace(0.0, cols - 1.0, 2),
                       indexing="ij")
    row, col = r.ravel(), c.ravel()
    h = np.full(row.shape, 0.5 * (h0 + h1))
    return (row, col, h) + _ground_sample(check, model, row, col, h)


def _isolation(
    check: str, model: Any, what: str, clean: Sequence[np.ndarray], dirty: Sequence[np.ndarray],
    bad: np.ndarray, out_names: Sequence[str], tols: Sequence[float], at: Callable[[int], str],
    nan_at_bad: bool = True,
) -> None:
    for name, a, b, tol in zip(out_names, clean, dirty, tols, strict=True):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            raise _error(check, model, f"{what}: {name} has shape {b.shape} with a NaN input but "
                         f"{a.shape} without")
        if nan_at_bad:
            leaked_out = bad & ~np.isnan(b).reshape(bad.shape + (-1,)).all(-1)
            if b.size == 0:
                leaked_out = np.zeros_like(bad)
            if leaked_out.any():
                i = int(np.flatnonzero(leaked_out)[0])
                raise _error(check, model, f"{what}: a non-finite input gives a non-NaN {name}",
                             at=at(i), expected="NaN", got=_g(b.reshape(bad.shape + (-1,))[i, 0]),
                             hint="NaN in, NaN out: a point with a non-finite coordinate has NaN "
                             "results and status INVALID_INPUT")
        good = ~bad
        if a.size == 0:  # e.g. the (*S, 2, 0) partials of a model without parameters
            continue
        a_ok, b_ok = a[good].reshape(int(good.sum()), -1), b[good].reshape(int(good.sum()), -1)
        diff = np.max(np.abs(a_ok - b_ok), axis=-1)
        leak = ~(diff <= tol)
        if leak.any():
            j = int(np.flatnonzero(leak)[0])
            i = int(np.flatnonzero(good)[j])
            raise _error(
                check, model,
                f"{what}: a non-finite input at point(s) {np.flatnonzero(bad).tolist()} changes "
                f"{name} at {int(leak.sum())} other point(s)",
                at=at(i), expected=f"{name}={np.array2string(a_ok[j], precision=10)} (as without "
                "the non-finite point)", got=f"{name}={np.array2string(b_ok[j], precision=10)}",
                hint="invalid points must not leak into others: compute per point, or mask "
                "non-finite inputs before any reduction over points (mean, norm, min/max, "
                "a shared iteration stop)",
            )


def check_nan_isolation(model: Any) -> None:
    """Non-finite inputs give NaN at their point only, with status ``INVALID_INPUT``.

    Six points inside the image at mid height are evaluated twice: as they are, and with NaN
    longitude (resp. row) at point 1, +inf latitude (resp. -inf column) at point 3 and NaN
    height at point 4. ``project``, ``backproject`` and their ``*_with_status`` variants must
    give NaN at those points, results identical to the clean call (1e-9 px, 1e-11 degree,
    1e-6 m) elsewhere, and status ``INVALID_INPUT`` there and ``CONVERGED`` elsewhere;
    ``partials_ground`` and ``partials_parameters`` with NaN at points 1, 3 and 4 must be
    unchanged elsewhere.

    Raises
    ------
    AssertionError
        Naming the method, the point and the leaked values.
    """
    check = "check_nan_isolation"
    row, col, h, lon, lat, hh = _nan_sample(model, check)
    bad = np.zeros(row.shape, bool)
    bad[[1, 3, 4]] = True
    d_lon, d_lat, d_h = lon.copy(), lat.copy(), hh.copy()
    d_lon[1], d_lat[3], d_h[4] = np.nan, np.inf, np.nan
    d_row, d_col, d_hb = row.copy(), col.copy(), h.copy()
    d_row[1], d_col[3], d_hb[4] = np.nan, -np.inf, np.nan

    def at_g(i: int) -> str:
        return (f"point {i}: {_at_ground(lon[i], lat[i], hh[i])} "
                f"(input {_at_ground(d_lon[i], d_lat[i], d_h[i])})")

    def at_i(i: int) -> str:
        return (f"point {i}: {_at_image(row[i], col[i], h[i])} "
                f"(input {_at_image(d_row[i], d_col[i], d_hb[i])})")

    img_tol, gnd_tol = (_SAME_PX, _SAME_PX), (_SAME_DEG, _SAME_DEG, _SAME_M)
    for what, func, clean_in, dirty_in, names, tols, at in (
        ("project", model.project, (lon, lat, hh), (d_lon, d_lat, d_h), ("row", "col"), img_tol,
         at_g),
        ("backproject", model.backproject, (row, col, h), (d_row, d_col, d_hb),
         ("lon", "lat", "h"), gnd_tol, at_i),
    ):
        clean = _call(check, model, f"{what} (finite inputs)", func, *clean_in)
        if not all(np.all(np.isfinite(a)) for a in clean):
            raise _error(check, model, f"{what} gives NaN for finite points inside the image")
        dirty = _call(check, model, f"{what} (with non-finite inputs)", func, *dirty_in)
        _isolation(check, model, what, clean, dirty, bad, names, tols, at)
        ws = what + "_with_status"
        out, status = _call(check, model, f"{ws} (with non-finite inputs)", getattr(model, ws),
                            *dirty_in)
        _isolation(check, model, ws, clean, out, bad, names, tols, at)
        status = np.asarray(status)
        expected = np.where(bad, _INVALID, _CONVERGED)
        if status.shape != bad.shape or not np.array_equal(status, expected):
            wrong = np.flatnonzero(status != expected) if status.shape == bad.shape else [0]
            i = int(wrong[0])
            raise _error(check, model, f"{ws}: wrong status", at=at(i),
                         expected=f"{_status_name(expected[i])} (statuses {expected.tolist()})",
                         got=f"statuses {status.tolist()}",
                         hint="a non-finite input coordinate gets Status.INVALID_INPUT, a "
                         "computed point Status.CONVERGED")
    # partials are evaluated at ground points, so only NaN (a missing point) is probed there
    d_lat[3] = np.nan
    for what, func, tol in (("partials_ground", model.partials_ground, 1e-9),
                            ("partials_parameters", model.partials_parameters, 1e-9)):
        clean = np.asarray(_call(check, model, f"{what} (finite inputs)", func, lon, lat, hh))
        dirty = np.asarray(_call(check, model, f"{what} (with NaN inputs)", func,
                                 d_lon, d_lat, d_h))
        scale = float(np.max(np.abs(clean))) if clean.size else 0.0
        _isolation(check, model, what, (clean,), (dirty,), bad, ("partials",),
                   (tol * max(scale, 1e-300) + 1e-300,), at_g, nan_at_bad=False)


def _expect_array(check: str, model: Any, what: str, value: Any, shape: tuple[int, ...],
                  dtype: Any = np.float64) -> None:
    if not isinstance(value, (np.ndarray, np.generic)):
        raise _error(check, model, f"{what} is not a numpy array",
                     expected=f"ndarray of shape {shape} {np.dtype(dtype)}",
                     got=f"{type(value).__qualname__} {value!r:.60}")
    if value.shape != shape or value.dtype != np.dtype(dtype):
        raise _error(check, model, f"{what} has the wrong shape or dtype",
                     expected=f"shape {shape} {np.dtype(dtype)}",
                     got=f"shape {value.shape} {value.dtype}",
                     hint="outputs have the broadcast shape S of the inputs (0-d for scalars, "
                     "(0,) for empty arrays) and are float64 (statuses uint8)")


def _expect_fields(check: str, model: Any, what: str, value: Any, fields: Sequence[str]) -> None:
    if not isinstance(value, tuple) or len(value) != len(fields) or not all(
        hasattr(value, f) for f in fields
    ):
        raise _error(check, model, f"{what} does not return a named tuple ({', '.join(fields)})",
                     got=f"{type(value).__qualname__} {value!r:.80}",
                     hint="return geoblock.typing.ImageCoords / GroundCoords")


def check_shapes(model: Any) -> None:
    """Outputs follow the inputs' broadcast shape and are float64.

    * 0-d (Python float and 0-d array) inputs give 0-d float64 outputs, (2, 3) and (2, P)
      partials and a 0-d uint8 status;
    * empty (0,) inputs give (0,) outputs, (0, 2, 3) and (0, 2, P) partials;
    * ``(3, 1) x (1, 4)`` inputs (and a scalar height) give (3, 4) outputs equal to the
      point-by-point evaluation, and (3, 4, 2, 3) and (3, 4, 2, P) partials;
    * ``project`` returns an ``ImageCoords`` (row, col), ``backproject`` a ``GroundCoords``.

    Raises
    ------
    AssertionError
        Naming the call, expected and obtained shape and dtype.
    """
    check = "check_shapes"
    rows, cols = model.shape
    h0, h1 = model.height_range
    hm = 0.5 * (h0 + h1)
    p = len(model.parameters.names)
    img = np.array([(rows - 1) / 4, (rows - 1) / 2, 3 * (rows - 1) / 4])
    img_c = np.array([(cols - 1) / 4, (cols - 1) / 2, 3 * (cols - 1) / 4])
    lon_s, lat_s, _ = _ground_sample(check, model, img, img_c, np.full(3, hm))
    lon0, lat0, row0, col0 = float(lon_s[1]), float(lat_s[1]), float(img[1]), float(img_c[1])

    def methods(kind: str) -> tuple[tuple[str, tuple[Any, ...], Callable[..., Any]], ...]:
        if kind == "ground":
            return (("project", ("row", "col"), model.project),
                    ("project_with_status", ("row", "col"), model.project_with_status),
                    ("partials_ground", (2, 3), model.partials_ground),
                    ("partials_parameters", (2, p), model.partials_parameters))
        return (("backproject", ("lon", "lat", "h"), model.backproject),
                ("backproject_with_status", ("lon", "lat", "h"), model.backproject_with_status))

    def verify(kind: str, args: tuple[ArrayLike, ArrayLike, ArrayLike], shape: tuple[int, ...],
               label: str) -> dict[str, Any]:
        results: dict[str, Any] = {}
        for name, fields, func in methods(kind):
            what = f"{name}({label})"
            out = _call(check, model, what, func, *args)
            results[name] = out
            if name.startswith("partials"):
                _expect_array(check, model, what, out, shape + fields)
                continue
            status = None
            if name.endswith("_with_status"):
                if not isinstance(out, tuple) or len(out) != 2:
                    raise _error(check, model, f"{what} does not return (coords, status)",
                                 got=f"{type(out).__qualname__} {out!r:.80}")
                out, status = out
            _expect_fields(check, model, what, out, fields)
            for f in fields:
                _expect_array(check, model, f"{what}.{f}", getattr(out, f), shape)
            if status is not None:
                _expect_array(check, model, f"{what} status", status, shape, np.uint8)
        return results

    # 0-d
    verify("ground", (lon0, lat0, hm), (), "python floats")
    verify("ground", (np.array(lon0), np.array(lat0), np.array(hm)), (), "0-d arrays")
    verify("image", (row0, col0, hm), (), "python floats")
    verify("image", (np.array(row0), np.array(col0), np.array(hm)), (), "0-d arrays")
    # empty
    e = np.zeros(0)
    verify("ground", (e, e, e), (0,), "empty (0,) arrays")
    verify("image", (e, e, e), (0,), "empty (0,) arrays")
    # broadcasting
    g_lon, g_lat = lon_s[[0, 1, 2]].reshape(3, 1), np.linspace(lat_s[0], lat_s[2], 4).reshape(1, 4)
    i_row, i_col = img.reshape(3, 1), np.linspace(img_c[0], img_c[2], 4).reshape(1, 4)
    for kind, args, label in (("ground", (g_lon, g_lat, hm), "lon (3, 1), lat (1, 4), scalar h"),
                              ("image", (i_row, i_col, hm), "row (3, 1), col (1, 4), scalar h")):
        results = verify(kind, args, (3, 4), label)
        flat_args = [a.ravel() for a in np.broadcast_arrays(*(np.asarray(a, float) for a in args))]
        for name, fields, func in methods(kind):
            if name.endswith("_with_status"):
                continue
            flat = np.asarray(_call(check, model, f"{name}(flat arrays)", func, *flat_args))
            grid = np.asarray(results[name])
            if name.startswith("partials"):
                grid = grid.reshape((12,) + grid.shape[2:])
                tol = 1e-9 * max(float(np.max(np.abs(flat))) if flat.size else 0.0, 1e-300)
            else:
                grid = grid.reshape(len(fields), 12)
                tol = _SAME_DEG if kind == "image" else _SAME_PX
            diff = np.abs(grid - flat)
            if not np.all(diff <= tol):
                raise _error(check, model, f"{name}({label}) differs from the same points given "
                             "as flat (12,) arrays",
                             expected=np.array2string(flat, precision=8)[:300],
                             got=np.array2string(grid, precision=8)[:300],
                             hint="broadcast the inputs together (np.broadcast_arrays) before "
                             "computing; do not pair them element by element in another order")


# ================================================================================ footprint
def _inside(px: float, py: float, x: np.ndarray, y: np.ndarray) -> bool:
    """Ray casting point-in-polygon (vertices not closed)."""
    inside = False
    xj, yj = x[-1], y[-1]
    for xi, yi in zip(x, y, strict=True):
        if (yi > py) != (yj > py) and px < (xj - xi) * (py - yi) / (yj - yi) + xi:
            inside = not inside
        xj, yj = xi, yi
    return inside


def check_footprint(model: Any, *, tolerance_px: float = 1e-6) -> None:
    """Probe the pixel-centre convention through the footprint and the pixel edges.

    * the four image corners (pixel edges ``-0.5`` and ``size - 0.5``) backproject at both
      ends of ``height_range``;
    * ``footprint()`` (when the model has one) runs, returns finite points at mid height whose
      projections lie on the pixel edges, the first at the corner ``(-0.5, -0.5)``;
    * the centre of pixel ``(0, 0)`` and the image centre ``((rows - 1) / 2, (cols - 1) / 2)``,
      backprojected at mid height, lie inside the footprint polygon, and the centre of the
      pixel ``(-1, -1)`` outside the image (when the model can backproject it) outside.

    Parameters
    ----------
    model : SensorModel
    tolerance_px : float
        Pixels.

    Raises
    ------
    AssertionError
    """
    check = "check_footprint"
    rows, cols = model.shape
    h0, h1 = model.height_range
    hm = 0.5 * (h0 + h1)
    corners_r = np.array([-0.5, -0.5, rows - 0.5, rows - 0.5] * 2)
    corners_c = np.array([-0.5, cols - 0.5, cols - 0.5, -0.5] * 2)
    corners_h = np.repeat([h0, h1], 4)
    _ground_sample(check, model, corners_r, corners_c, corners_h)
    footprint = getattr(model, "footprint", None)
    if callable(footprint):
        fp = _call(check, model, "footprint()", footprint)
        _expect_fields(check, model, "footprint()", fp, ("lon", "lat", "h"))
        f_lon, f_lat, f_h = (np.asarray(a, dtype=np.float64) for a in fp)
        if f_lon.ndim != 1 or f_lon.size < 4 or not (
            np.all(np.isfinite(f_lon)) and np.all(np.isfinite(f_lat))
        ):
            raise _error(check, model, "footprint() is not a finite (4 n,) outline",
                         got=f"shape {f_lon.shape}, {int(np.sum(~np.isfinite(f_lon)))} NaN",
                         hint="the pixel edges -0.5 and size - 0.5 must be inside the "
                         "model's domain")
        if not np.allclose(f_h, hm, rtol=0, atol=_SAME_M):
            raise _error(check, model,
                         "footprint() is not at the middle of height_range by default",
                         expected=f"h={_g(hm)} m", got=f"h={_g(f_h[0])} m")
        (f_r, f_c), _ = _call(check, model, "project_with_status(footprint())",
                              model.project_with_status, f_lon, f_lat, f_h)
        if not (abs(f_r[0] + 0.5) <= tolerance_px and abs(f_c[0] + 0.5) <= tolerance_px):
            centre = abs(f_r[0]) < 0.01 and abs(f_c[0]) < 0.01
            raise _error(check, model,
                         "the first footprint vertex is not the outer corner of pixel "
                         "(0, 0)", expected="row=-0.5, col=-0.5",
                         got=f"row={_g(f_r[0])}, col={_g(f_c[0])}",
                         hint="the footprint starts at the centre of pixel (0, 0): it must follow "
                         "the pixel edges (-0.5 .. size - 0.5)" if centre else
                         "footprint() starts at the top-left corner (-0.5, -0.5) of the image")
        edge = np.min(np.abs(np.stack([f_r + 0.5, f_r - (rows - 0.5), f_c + 0.5,
                                       f_c - (cols - 0.5)])), axis=0)
        if np.any(~(edge <= tolerance_px)):
            i = int(np.argmax(np.where(np.isnan(edge), np.inf, edge)))
            raise _error(check, model, f"footprint vertex {i} is not on the image's pixel edges",
                         at=_at_ground(f_lon[i], f_lat[i], f_h[i]),
                         expected=f"row in (-0.5, {rows - 0.5}) or col in (-0.5, {cols - 0.5})",
                         got=f"row={_g(f_r[i])}, col={_g(f_c[i])}",
                         hint="the image covers [-0.5, rows - 0.5) x [-0.5, cols - 0.5): "
                         "integers are pixel centres")
    else:
        t = np.linspace(0.0, 1.0, 8, endpoint=False)
        r0, r1, c0, c1 = -0.5, rows - 0.5, -0.5, cols - 0.5
        e_r = np.concatenate(
            [np.full(8, r0), r0 + (r1 - r0) * t, np.full(8, r1), r1 - (r1 - r0) * t])
        e_c = np.concatenate(
            [c0 + (c1 - c0) * t, np.full(8, c1), c1 - (c1 - c0) * t, np.full(8, c0)])
        f_lon, f_lat, _ = _ground_sample(check, model, e_r, e_c, np.full(e_r.shape, hm))
    frame = coords.LocalFrame(float(np.mean(f_lon)), float(np.mean(f_lat)), hm)
    poly_e, poly_n, _ = frame.from_geodetic(f_lon, f_lat, np.full(f_lon.shape, hm))
    probes_r = np.array([0.0, (rows - 1) / 2.0])
    probes_c = np.array([0.0, (cols - 1) / 2.0])
    p_lon, p_lat, _ = _ground_sample(check, model, probes_r, probes_c, np.full(2, hm))
    p_e, p_n, _ = frame.from_geodetic(p_lon, p_lat, np.full(2, hm))
    for j, label in enumerate(("the centre of pixel (0, 0)", "the image centre")):
        if not _inside(float(p_e[j]), float(p_n[j]), poly_e, poly_n):
            raise _error(check, model, f"{label} is outside the footprint",
                         at=_at_image(probes_r[j], probes_c[j], hm),
                         got=_at_ground(p_lon[j], p_lat[j], hm),
                         hint="backproject and footprint disagree on the pixel convention: "
                         "(0, 0) is the centre of the first pixel, half a pixel inside the "
                         "image's corner (-0.5, -0.5)")
    (o_lon, o_lat, _), status = _call(check, model, "backproject_with_status(-1, -1, h)",
                                      model.backproject_with_status, -1.0, -1.0, hm)
    if int(status) == _CONVERGED:
        o_e, o_n, _ = frame.from_geodetic(o_lon, o_lat, hm)
        if _inside(float(o_e), float(o_n), poly_e, poly_n):
            raise _error(check, model, "the centre of pixel (-1, -1), outside the image, is inside "
                         "the footprint", at=_at_image(-1.0, -1.0, hm),
                         hint="the footprint extends beyond the pixel edges: it must run along "
                         "row/col = -0.5 and size - 0.5")


# ================================================================================ all together
#: Every check, in the order :func:`check_sensor_model` runs them.
CHECKS: tuple[Callable[..., object], ...] = (
    check_metadata,
    check_shapes,
    check_round_trip,
    check_footprint,
    check_nan_isolation,
    check_ground_partials,
    check_parameter_partials,
    check_parameter_perturbation,
    check_with_parameters,
    check_parameter_sets,
    check_no_mutation,
    check_serialization,
    check_pickle,
    check_dask_token,
    check_partials_together,
)


def _options_for(func: Callable[..., object], options: Mapping[str, Any]) -> dict[str, Any]:
    """The subset of ``check_sensor_model`` options a check accepts, renamed."""
    accepted = inspect.signature(func).parameters
    renamed = dict(options)
    if "rtol" in accepted:
        key = "perturbation_rtol" if func is check_parameter_perturbation else "partials_rtol"
        if key in options:
            renamed["rtol"] = options[key]
    return {k: v for k, v in renamed.items() if k in accepted}


def check_sensor_model(
    model: Any,
    *,
    n: int = 5,
    seed: int = 0,
    tolerance_px: float = 1e-6,
    partials_rtol: float = 1e-4,
    perturbation_rtol: float = 0.1,
    parameter_set_options: Mapping[str, Mapping[str, Any]] | None = None,
    skip: Sequence[str] = (),
) -> None:
    """Run every conformance check on a sensor model.

    Any object following the :class:`~geoblock.models.SensorModel` protocol can be checked,
    whether or not it subclasses :class:`~geoblock.models.SensorModelBase`. The checks
    (:data:`CHECKS`) are :func:`check_metadata`, :func:`check_shapes`,
    :func:`check_round_trip`, :func:`check_footprint`, :func:`check_nan_isolation`,
    :func:`check_ground_partials`, :func:`check_parameter_partials`,
    :func:`check_parameter_perturbation`, :func:`check_with_parameters`,
    :func:`check_parameter_sets`, :func:`check_no_mutation`, :func:`check_serialization`,
    :func:`check_pickle` and :func:`check_dask_token`.

    Parameters
    ----------
    model : SensorModel
        The model to check.
    n : int
        Grid points per image side of the sample (see :func:`image_sample`); the samples
        span the pixel edges and both ends of ``height_range``.
    seed : int
        Seed of the random part of the sample.
    tolerance_px : float
        Round-trip tolerance, pixels.
    partials_rtol : float
        Relative tolerance of analytic vs numeric partials.
    perturbation_rtol : float
        Relative tolerance of the motion predicted by the parameter partials.
    parameter_set_options : mapping of str to mapping, optional
        Options of the parameter sets that need some (``{"dg": {"accuracy_m": 10.0}}``);
        :func:`check_parameter_sets` leaves out a set that needs options not given here.
    skip : sequence of str
        Names of checks not to run (e.g. ``["check_dask_token"]``).

    Raises
    ------
    AssertionError
        Listing every failed check with its point, expected and obtained values and a hint.

    Examples
    --------
    >>> from geoblock.testing.synthetic import AffineCamera
    >>> check_sensor_model(AffineCamera.example(), n=3)
    """
    options = {"n": n, "seed": seed, "tolerance_px": tolerance_px,
               "partials_rtol": partials_rtol, "perturbation_rtol": perturbation_rtol,
               "parameter_set_options": parameter_set_options}
    unknown = set(skip) - {c.__name__ for c in CHECKS}
    if unknown:
        raise ValueError(f"check_sensor_model: unknown checks {sorted(unknown)}")
    failures = []
    for check in CHECKS:
        if check.__name__ in skip:
            continue
        try:
            check(model, **_options_for(check, options))
        except AssertionError as exc:
            failures.append(str(exc))
    if failures:
        head = (f"{len(failures)} of {len(CHECKS) - len(skip)} conformance checks failed for "
                f"{_label(model)}")
        raise AssertionError(head + ":\n\n" + "\n\n".join(failures))
