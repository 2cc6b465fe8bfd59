"""Fit Chen & Lee's polynomial orientation to any sensor model over its scene.

This is how MBA starts from on-board data: the DIMAP line-of-sight model (or any other
:class:`~geoblock.models.protocol.SensorModel`) generates a 3D grid of ground points, and the
19 parameters of :class:`~geoblock_spot.chenlee.ChenLeeModel` are fitted to them by
Gauss-Newton with the analytic partials; the fit error is reported in pixels.

The fitted model's interior geometry (:class:`~geoblock_spot.chenlee.Interior`: line period,
pixel size, focal length) is the source's own when it can be known (:func:`source_interior`):
the ``mba`` set derives its a-priori sigmas from the scene duration and swath, so a wrong
interior would make them silently wrong.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from geoblock import coords
from geoblock.errors import AdjustmentError, GeoblockWarning, ParameterSetError
from geoblock.models.linescan import LinescanModel
from geoblock.models.protocol import SensorModel
from geoblock.typing import Status
from geoblock_spot.chenlee import SPOT1A_INTERIOR, ChenLeeModel, Interior

__all__ = ["NOMINAL_FOCAL_LENGTH_M", "ChenLeeFit", "InteriorWarning", "fit_chenlee",
           "source_interior"]

NOMINAL_FOCAL_LENGTH_M: float = SPOT1A_INTERIOR.focal_length_m
"""Focal length given to an interior derived from look directions, metres (SPOT HRV and HRG:
1.082 m). Look directions are angles: they fix ``pixel_size / focal_length`` (the angular
pixel), which is all the Chen & Lee model uses, not the focal length itself."""


class InteriorWarning(GeoblockWarning):
    """:func:`fit_chenlee` cannot know the source model's interior geometry (line period,
    angular pixel) and falls back to SPOT 1A's (:data:`~geoblock_spot.chenlee.SPOT1A_INTERIOR`):
    the fitted geometry is right, but its time scale (``t = row * line_period``) and
    ``Sy`` are SPOT 1A's, and ``mba`` sigmas derived later from them would be wrong."""


@dataclass(frozen=True)
class ChenLeeFit:
    """Outcome of :func:`fit_chenlee`.

    Attributes
    ----------
    model : ChenLeeModel
        The fitted model (``"coefficients"`` set, or ``"mba"`` when asked).
    rms_px, max_px : float
        Fit error on the fitting grid: RMS and maximum of the image distance
        ``hypot(d row, d col)`` between the source model and the fitted one, pixels.
    check_rms_px, check_max_px : float
        The same on an independent check grid (cell centres of the fitting grid, at heights
        between the fitting heights).
    n_points, n_check : int
        Ground points used for the fit and for the check.
    converged : bool
    iterations : int
    history : list of dict
        Per Gauss-Newton iteration: ``rms_px`` before the step and ``max_step_px`` (largest
        predicted image motion of the step).
    interior_source : {"given", "source", "assumed SPOT 1A"}
        Where the fitted model's interior came from: the ``interior`` argument, the source
        model (:func:`source_interior`), or SPOT 1A's for want of either (with an
        :class:`InteriorWarning`). ``model.scene_duration_s`` is ``rows * line_period``.
    """

    model: ChenLeeModel
    rms_px: float
    max_px: float
    check_rms_px: float
    check_max_px: float
    n_points: int
    n_check: int
    converged: bool
    iterations: int
    history: list[dict] = field(repr=False)
    interior_source: str = "given"


def source_interior(model: SensorModel) -> Interior | None:
    """The interior geometry of a sensor model, when its public description gives it.

    * a :class:`~geoblock_spot.chenlee.ChenLeeModel`: its own :attr:`interior`;
    * a :class:`geoblock.models.linescan.LinescanModel` (the simulator's models, the SPOT
      DIMAP and DIMAP v2 line-of-sight models): the line period of its
      :attr:`~geoblock.models.linescan.LinescanModel.line_times`, and the angular pixel
      ``pixel_size / focal_length = 2 tan(theta / 2) / (cols - 1)`` of its look directions,
      ``theta`` the angle between the first and last detectors' (that of a pinhole array
      centred on its boresight, whatever the tilt of the sensor frame: SPOT 1-4's look
      directions hold the mirror's), as ``pixel_size_m`` behind
      :data:`NOMINAL_FOCAL_LENGTH_M` (a SPOT scene gets its CCD pitch: 13 um for HRV
      panchromatic, 6.5 um for HRG's 5 m);
    * anything else (an RPC model, ...): None.

    Parameters
    ----------
    model : SensorModel

    Returns
    -------
    Interior or None
    """
    if isinstance(model, ChenLeeModel):
        return model.interior
    if isinstance(model, LinescanModel):
        v = model.look.vectors  # (cols, 3) unit vectors, sensor frame
        first, last = v[0], v[-1]
        angle = math.atan2(float(np.linalg.norm(np.cross(first, last))), float(first @ last))
        pitch = 2.0 * math.tan(angle / 2.0) / (v.shape[0] - 1)
        return Interior(pixel_size_m=NOMINAL_FOCAL_LENGTH_M * pitch,
                        focal_length_m=NOMINAL_FOCAL_LENGTH_M,
                        line_period_s=model.line_times.line_period_s)
    return None


def _grid(shape: tuple[int, int], n: tuple[int, int], heights: np.ndarray, centres: bool):
    rows, cols = shape
    nr, nc = n
    if centres:
        r = -0.5 + (np.arange(nr - 1) + 0.5) * rows / (nr - 1)
        c = -0.5 + (np.arange(nc - 1) + 0.5) * cols / (nc - 1)
    else:
        r = np.linspace(-0.5, rows - 0.5, nr)
        c = np.linspace(-0.5, cols - 0.5, nc)
    rr, cc, hh = np.meshgrid(r, c, heights, indexing="ij")
    return rr.ravel(), cc.ravel(), hh.ravel()


def _ground_points(model: SensorModel, row, col, h):
    (lon, lat, hh), status = model.backproject_with_status(row, col, h)
    ok = status == Status.CONVERGED
    return row[ok], col[ok], lon[ok], lat[ok], hh[ok]


def default_frame(model: SensorModel) -> coords.LocalFrame:
    """A work frame at the image centre (on the middle of the height range) with ``X`` along
    the ground track (direction of increasing rows): Teo et al.'s LVLH-like axes."""
    rows, cols = model.shape
    h = 0.5 * (model.height_range[0] + model.height_range[1])
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    g, status = model.backproject_with_status(
        np.array([rc, rc - rows / 4.0, rc + rows / 4.0]), np.full(3, cc), np.full(3, h)
    )
    if np.any(status != Status.CONVERGED):
        raise AdjustmentError(
            f"fit_chenlee: the {model.name!r} model cannot backproject its image centre at "
            f"h = {h:g} m; give a frame"
        )
    de, dn, _ = coords.enu_offsets(g.lon[1], g.lat[1], h, g.lon[2], g.lat[2], h)
    return coords.LocalFrame(float(g.lon[0]), float(g.lat[0]), h,
                             math.degrees(math.atan2(de, dn)))


def _initial_coefficients(model: SensorModel, frame: coords.LocalFrame,
                          interior: Interior) -> np.ndarray:
    """First guess: per sampled line, the perspective centre (least-squares meeting point of the
    line's rays) and the rotation that puts those rays in the plane x = 0; then quadratic fits
    in t of the centres and angles, and ``Sy`` from the ray directions."""
    rows, cols = model.shape
    h0, h1 = model.height_range
    lines = np.linspace(-0.5, rows - 0.5, 9)
    pixels = np.linspace(-0.5, cols - 0.5, 11)
    rr, cc = np.meshgrid(lines, pixels, indexing="ij")
    top, s_top = model.backproject_with_status(rr, cc, np.full(rr.shape, h1))
    low, s_low = model.backproject_with_status(rr, cc, np.full(rr.shape, h0))
    if np.any(s_top != Status.CONVERGED) or np.any(s_low != Status.CONVERGED):
        raise AdjustmentError(
            f"fit_chenlee: the {model.name!r} model cannot backproject its image corners and "
            "edges over its height range"
        )
    a = np.stack(frame.from_geodetic(*top), axis=-1)  # (L, K, 3) work frame
    b = np.stack(frame.from_geodetic(*low), axis=-1)
    d = b - a
    d /= np.linalg.norm(d, axis=-1, keepdims=True)  # down the line of sight
    proj = np.eye(3) - d[..., :, None] * d[..., None, :]  # (L, K, 3, 3)
    rhs = np.einsum("lkij,lkj->li", proj, a)[..., None]
    centres = np.linalg.solve(proj.sum(axis=1), rhs)[..., 0]  # (L, 3)
    along = centres[-1] - centres[0]
    c0 = (cols - 1) / 2.0
    angles = []
    sy = []
    for k in range(lines.size):
        _, _, vt = np.linalg.svd(d[k])
        r1 = vt[-1] * np.sign(vt[-1] @ along)  # normal of the line's fan of rays
        view = np.mean(d[k], axis=0)
        r3 = -(view - (view @ r1) * r1)
        r3 /= np.linalg.norm(r3)
        r2 = np.cross(r3, r1)
        u = (a[k] - centres[k]) @ np.stack([r1, r2, r3]).T
        y = (pixels - c0) * interior.pixel_size_m
        use = np.abs(y) > 0.1 * np.max(np.abs(y))
        s = np.median(-interior.focal_length_m * u[use, 1] / (u[use, 2] * y[use]))
        if s < 0:  # mirrored: turn the image x axis around
            r1, r2, s = -r1, -r2, -s
        sy.append(s)
        phi = math.asin(max(-1.0, min(1.0, r3[0])))
        omega = math.atan2(-r3[1], r3[2])
        kappa = math.atan2(-r2[0], r1[0])
        angles.append((omega, phi, kappa))
    angles = np.unwrap(np.array(angles), axis=0)
    t = (lines + 0.0) * interior.line_period_s
    design = np.stack([np.ones_like(t), t, t * t], axis=-1)
    orbit = np.linalg.lstsq(design, centres, rcond=None)[0].T  # (3 axes, 3 powers)
    att = np.linalg.lstsq(design, angles, rcond=None)[0].T
    return np.concatenate([orbit.ravel(), att.ravel(), [float(np.median(sy))]])


def fit_chenlee(
    model: SensorModel,
    *,
    interior: Interior | None = None,
    frame: coords.LocalFrame | None = None,
    heights: np.ndarray | None = None,
    grid: tuple[int, int] = (15, 15),
    max_iterations: int = 50,
    tolerance_px: float = 1e-8,
    location_accuracy_m: float | None = None,
) -> ChenLeeFit:
    """Fit Chen & Lee's model (19 parameters) to any sensor model over its scene.

    A 3D grid of image points (``grid`` rows x columns spanning the image, pixel edges
    included, at each of ``heights``) is backprojected through ``model``; the Chen & Lee
    parameters are then fitted to these ground/image pairs by Gauss-Newton with the analytic
    partials (column-scaled least squares), starting from per-line perspective centres and
    rotations of the source model's rays.

    Parameters
    ----------
    model : SensorModel
        The source, e.g. a DIMAP line-of-sight model.
    interior : Interior, optional
        Interior geometry of the fitted model (line period, pixel size, focal length); default
        the source's (:func:`source_interior`: a linescan model's line period and angular
        pixel, a Chen & Lee model's interior). Only ``focal_length / pixel_size`` and the line
        period enter the model, and errors in them are absorbed by ``Sy`` and the time
        polynomials; but the ``mba`` sigmas scale with the scene duration ``rows *
        line_period`` and the swath, so they need the right values. When the source does not
        tell (e.g. an RPC model) and none is given, SPOT 1A's is used with an
        :class:`InteriorWarning`, and ``location_accuracy_m`` is refused.
    frame : geoblock.coords.LocalFrame, optional
        Work frame; default :func:`default_frame` (image centre, ``X`` along track).
    heights : array_like, optional
        Heights of the grid, metres; default 5 levels spanning ``model.height_range``.
    grid : (int, int)
        Grid points along rows and columns.
    max_iterations : int
        Iteration cap of Gauss-Newton (its convergence is linear when the polynomial form
        cannot represent the source exactly: about 30 iterations for the SPOT 1-4 DIMAP
        models to reach 1e-8 px steps).
    tolerance_px : float
        Converged when the step moves no grid point by more than this, pixels.
    location_accuracy_m : float, optional
        If given, the result is in the ``mba`` set with sigmas from this stated accuracy
        (:meth:`ChenLeeModel.mba_sigmas`), ready for :func:`geoblock.adjust.resect`.

    Returns
    -------
    ChenLeeFit
        The model and the fit error in pixels (max/RMS) on the grid and on a check grid.

    Raises
    ------
    ParameterSetError
        ``location_accuracy_m`` is given but the interior is neither given nor known from the
        source (the ``mba`` sigmas need the scene duration).
    AdjustmentError
        The source model cannot backproject its grid or the fit is singular.

    Warns
    -----
    InteriorWarning
        The interior is neither given nor known from the source: SPOT 1A's is used.
    """
    interior_source = "given"
    if interior is None:
        interior = source_interior(model)
        interior_source = "source"
    if interior is None:
        if location_accuracy_m is not None:
            raise ParameterSetError(
                f"fit_chenlee: the {model.name!r} model does not tell its line period and "
                "pixel size, from which the mba sigmas derive (scene duration, swath); give "
                "interior=Interior(pixel_size_m=..., focal_length_m=..., line_period_s=...)")
        warnings.warn(
            f"fit_chenlee: the {model.name!r} model does not tell its line period and pixel "
            "size; the fitted model uses SPOT 1A's (1.5 ms, 13 um, 1.082 m): its time scale "
            "and Sy are SPOT 1A's. Give interior=Interior(...) to avoid this",
            InteriorWarning, stacklevel=2)
        interior, interior_source = SPOT1A_INTERIOR, "assumed SPOT 1A"
    if frame is None:
        frame = default_frame(model)
    h0, h1 = model.height_range
    heights = (np.linspace(h0, h1, 5) if heights is None
               else np.atleast_1d(np.asarray(heights, float)))
    row, col, lon, lat, h = _ground_points(model, *_grid(model.shape, grid, heights, False))
    if row.size < 19:
        raise AdjustmentError(
            f"fit_chenlee: only {row.size} grid points backproject through {model.name!r}; "
            "the 19 parameters need more (check the model's height range)"
        )
    mid = 0.5 * (heights[1:] + heights[:-1]) if heights.size > 1 else heights
    c_row, c_col, c_lon, c_lat, c_h = _ground_points(model, *_grid(model.shape, grid, mid, True))
    kwargs = {"shape": tuple(model.shape), "interior": interior,
              "height_range": tuple(model.height_range)}
    x = _initial_coefficients(model, frame, interior)
    observed = np.stack([row, col], axis=-1)
    history: list[dict] = []
    converged = False
    current = ChenLeeModel(x, frame, **kwargs)
    for _ in range(max_iterations):
        current = ChenLeeModel(x, frame, **kwargs)
        (r, c), status = current.project_with_status(lon, lat, h)
        if np.any(status != Status.CONVERGED):
            raise AdjustmentError(
                f"fit_chenlee: the fit left the scene ({int((status != 0).sum())} grid points "
                "do not project); give a frame or heights closer to the scene"
            )
        v = (observed - np.stack([r, c], axis=-1)).ravel()
        jac = current.partials_parameters(lon, lat, h).reshape(-1, 19)
        norms = np.linalg.norm(jac, axis=0)
        norms[norms == 0] = 1.0
        step, *_ = np.linalg.lstsq(jac / norms, v, rcond=1e-13)
        step /= norms
        motion = float(np.max(np.abs(jac @ step)))
        history.append({"rms_px": float(np.sqrt(np.mean(v**2) * 2)), "max_step_px": motion})
        x = x + step
        if motion <= tolerance_px:
            converged = True
            break
    fitted = ChenLeeModel(x, frame, **kwargs)
    err = _errors(fitted, row, col, lon, lat, h)
    check = _errors(fitted, c_row, c_col, c_lon, c_lat, c_h)
    if location_accuracy_m is not None:
        fitted = fitted.mba(location_accuracy_m)
    return ChenLeeFit(
        model=fitted,
        rms_px=float(np.sqrt(np.mean(err**2))),
        max_px=float(np.max(err)),
        check_rms_px=float(np.sqrt(np.mean(check**2))) if check.size else float("nan"),
        check_max_px=float(np.max(check)) if check.size else float("nan"),
        n_points=int(row.size),
        n_check=int(c_row.size),
        converged=converged,
        iterations=len(history),
        history=history,
        interior_source=interior_source,
    )


def _errors(model: ChenLeeModel, row, col, lon, lat, h) -> np.ndarray:
    (r, c), status = model.project_with_status(lon, lat, h)
    err = np.hypot(r - row, c - col)
    return np.where(status == Status.CONVERGED, err, np.inf)
