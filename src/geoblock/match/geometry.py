"""What the sensor models say about a pair of images: predictions, epipolar directions, local
affinities and overlaps, all through the DEM.

For a pixel ``a`` of image A, :func:`predict` intersects A's line of sight with the DEM
(:func:`geoblock.localize`) and projects the ground point into image B: the **prediction**
``p = P_B(L_A(a))``. The same line of sight at a height ``dh`` higher projects to
``p + e * dh``: ``e`` (pixels of B per metre) is the **epipolar direction** of ``a`` in B,
along which a height error of the DEM (or of A's model on sloping ground) moves the true
match. :func:`local_affine` is the derivative of ``a -> p`` on the DEM surface (how a patch of
A looks in B), :func:`overlap` the part of A whose ground the DEM places inside B.

Every function is vectorised over points; pixels are the models' (pixel centres at integers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from geoblock import coords
from geoblock.dem.intersect import localize
from geoblock.pixels import image_domain
from geoblock.typing import Status

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel

__all__ = ["EPIPOLAR_STEP_M", "Overlap", "Prediction", "ground_sample_distance", "local_affine",
           "overlap", "predict"]

#: Height step of the epipolar direction's finite difference, metres.
EPIPOLAR_STEP_M = 50.0


@dataclass(frozen=True, eq=False)
class Prediction:
    """Where image B should see pixels of image A, according to the models and the DEM.

    Attributes
    ----------
    row, col : ndarray, (N,)
        The prediction in B, pixels (NaN where ``ok`` is False).
    h : ndarray, (N,)
        Height of A's line of sight on the DEM, metres above the ellipsoid.
    epi_row, epi_col : ndarray, (N,)
        Epipolar direction in B: the prediction's motion per metre of height along A's line
        of sight, pixels per metre.
    ok : ndarray of bool, (N,)
        A's line of sight met the DEM and B's model projected the point inside B's image
        (within ``margin_px``).
    """

    row: np.ndarray
    col: np.ndarray
    h: np.ndarray
    epi_row: np.ndarray
    epi_col: np.ndarray
    ok: np.ndarray

    @property
    def epipolar_norm(self) -> np.ndarray:
        """``|e|``, pixels of B per metre of height, (N,)."""
        return np.hypot(self.epi_row, self.epi_col)


def _inside(model: SensorModel, row: np.ndarray, col: np.ndarray, margin_px: float
            ) -> np.ndarray:
    r0, c0, r1, c1 = image_domain(model.shape)
    with np.errstate(invalid="ignore"):
        return ((row >= r0 - margin_px) & (row <= r1 + margin_px)
                & (col >= c0 - margin_px) & (col <= c1 + margin_px))


def predict(model_a: SensorModel, model_b: SensorModel, dem: DemSource, row: np.ndarray,
            col: np.ndarray, *, margin_px: float = 0.0,
            dh_m: float = EPIPOLAR_STEP_M) -> Prediction:
    """Predict where B sees pixels of A: A's line of sight on the DEM, projected into B.

    Parameters
    ----------
    model_a, model_b : SensorModel
        The two images' models (pixels of each image).
    dem : DemSource
        Heights above the ellipsoid.
    row, col : ndarray, (N,)
        Pixels of A.
    margin_px : float
        How far outside B's image a prediction may fall and still be ``ok``, pixels.
    dh_m : float
        Height step of the epipolar direction's finite difference, metres.

    Returns
    -------
    Prediction
    """
    row = np.asarray(row, float).ravel()
    col = np.asarray(col, float).ravel()
    ground, status = localize(model_a, row, col, dem, warn=False)
    ok = status == Status.CONVERGED
    (rb, cb), st_b = model_b.project_with_status(ground.lon, ground.lat, ground.h)
    up, st_up = model_a.backproject_with_status(row, col, ground.h + dh_m)
    (rb2, cb2), st_b2 = model_b.project_with_status(up.lon, up.lat, up.h)
    ok &= (st_b == Status.CONVERGED) & (st_up == Status.CONVERGED) & (st_b2 == Status.CONVERGED)
    ok &= np.isfinite(rb) & np.isfinite(cb) & np.isfinite(rb2) & np.isfinite(cb2)
    ok &= _inside(model_b, rb, cb, margin_px)
    nan = np.where(ok, 1.0, np.nan)
    return Prediction(rb * nan, cb * nan, ground.h * nan, (rb2 - rb) / dh_m * nan,
                      (cb2 - cb) / dh_m * nan, ok)


def local_affine(model_a: SensorModel, model_b: SensorModel, dem: DemSource, row: np.ndarray,
                 col: np.ndarray, *, step_px: float = 2.0) -> np.ndarray:
    """The derivative of A's pixels -> B's pixels through the DEM surface at ``(row, col)``.

    Central differences of :func:`predict` ``step_px`` pixels apart along A's rows and
    columns: a patch of A centred on ``(row, col)`` is seen in B as its affine image.

    Parameters
    ----------
    model_a, model_b : SensorModel
    dem : DemSource
    row, col : ndarray, (N,)
        Pixels of A.
    step_px : float
        Half the finite-difference step, pixels of A.

    Returns
    -------
    ndarray, (N, 2, 2)
        ``J[n] = [[d row_b / d row_a, d row_b / d col_a], [d col_b / d row_a,
        d col_b / d col_a]]``; the identity where a difference failed (no DEM, outside B).
    """
    row = np.asarray(row, float).ravel()
    col = np.asarray(col, float).ravel()
    n = row.size
    s = float(step_px)
    rr = np.concatenate([row - s, row + s, row, row])
    cc = np.concatenate([col, col, col - s, col + s])
    p = predict(model_a, model_b, dem, rr, cc, margin_px=math.inf)
    pr = p.row.reshape(4, n)
    pc = p.col.reshape(4, n)
    jac = np.empty((n, 2, 2))
    jac[:, 0, 0] = (pr[1] - pr[0]) / (2 * s)
    jac[:, 1, 0] = (pc[1] - pc[0]) / (2 * s)
    jac[:, 0, 1] = (pr[3] - pr[2]) / (2 * s)
    jac[:, 1, 1] = (pc[3] - pc[2]) / (2 * s)
    bad = ~np.isfinite(jac).all(axis=(1, 2))
    jac[bad] = np.eye(2)
    return jac


@dataclass(frozen=True)
class Overlap:
    """The part of image A whose ground (on the DEM) image B sees.

    Attributes
    ----------
    fraction : float
        Share of A's area (a regular grid of its pixels) that B sees, in [0, 1].
    window_a : (int, int, int, int) or None
        ``(row_start, row_stop, col_start, col_stop)`` of A enclosing that part (one grid
        step of margin); None without overlap.
    window_b : (int, int, int, int) or None
        The same for the predictions of that part in B.
    centre_b : (float, float)
        The median prediction in B, pixels (NaN without overlap).
    height_m : float
        Median height of the overlap on the DEM, metres above the ellipsoid (NaN without
        overlap).
    """

    fraction: float
    window_a: tuple[int, int, int, int] | None
    window_b: tuple[int, int, int, int] | None
    centre_b: tuple[float, float] = (math.nan, math.nan)
    height_m: float = math.nan


def _window(row: np.ndarray, col: np.ndarray, pad: float, shape: tuple[int, int]
            ) -> tuple[int, int, int, int]:
    rows, cols = shape
    return (max(0, math.floor(float(row.min()) - pad)), min(rows, math.ceil(float(row.max())
                                                                            + pad) + 1),
            max(0, math.floor(float(col.min()) - pad)), min(cols, math.ceil(float(col.max())
                                                                            + pad) + 1))


def overlap(model_a: SensorModel, model_b: SensorModel, dem: DemSource, *, n: int = 24
            ) -> Overlap:
    """Which part of A image B sees: a grid of ``n x n`` pixels of A on the DEM, into B.

    Parameters
    ----------
    model_a, model_b : SensorModel
    dem : DemSource
    n : int
        Grid points per side.

    Returns
    -------
    Overlap
    """
    rows, cols = (int(v) for v in model_a.shape)
    r = np.linspace(0, rows - 1, n)
    c = np.linspace(0, cols - 1, n)
    rr, cc = (v.ravel() for v in np.meshgrid(r, c, indexing="ij"))
    p = predict(model_a, model_b, dem, rr, cc)
    if not p.ok.any():
        return Overlap(0.0, None, None)
    step = max(rows, cols) / max(n - 1, 1)
    window_a = _window(rr[p.ok], cc[p.ok], step, (rows, cols))
    # B's side: the predictions, widened by the grid step scaled into B
    steps = np.hypot(np.diff(p.row.reshape(n, n), axis=1), np.diff(p.col.reshape(n, n), axis=1))
    steps = steps[np.isfinite(steps)]
    scale = float(np.median(steps)) / max(c[1] - c[0], 1.0) if steps.size else 1.0
    window_b = _window(p.row[p.ok], p.col[p.ok], step * scale,
                       tuple(int(v) for v in model_b.shape))  # type: ignore[arg-type]
    centre = (float(np.median(p.row[p.ok])), float(np.median(p.col[p.ok])))
    return Overlap(float(p.ok.mean()), window_a, window_b, centre, float(np.median(p.h[p.ok])))


def ground_sample_distance(model: SensorModel, row: float, col: float, h: float) -> float:
    """Ground sample distance of ``model`` at pixel ``(row, col)`` on height ``h``, metres:
    the square root of the ground area of one pixel (NaN where it does not backproject)."""
    r = np.array([row, row, row - 0.5, row + 0.5])
    c = np.array([col - 0.5, col + 0.5, col, col])
    g, _ = model.backproject_with_status(r, c, np.full(4, float(h)))
    de, dn, _ = coords.enu_offsets(g.lon[0], g.lat[0], h, g.lon[1:], g.lat[1:], np.full(3, h))
    # d(e, n)/d(col) and d(e, n)/d(row), per pixel
    area = abs(de[0] * (dn[2] - dn[1]) - dn[0] * (de[2] - de[1]))
    return float(math.sqrt(area)) if math.isfinite(area) else math.nan
