"""Pieces the single-image resection and the block engine share: a-priori weights of
parameters and ground points, and the diagnosis of undetermined unknowns."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from geoblock import coords
from geoblock.typing import ArrayLike

__all__ = ["ground_covariance", "prior_weight", "undetermined"]


def prior_weight(covariance: np.ndarray) -> np.ndarray:
    """(K, K) weight matrix of a-priori parameter values: the inverse of the covariance on the
    parameters whose sigma is finite, zero rows and columns for free (infinite-sigma) ones."""
    finite = np.isfinite(np.diag(covariance))
    weight = np.zeros_like(covariance, dtype=np.float64)
    if finite.any():
        sub = np.ix_(finite, finite)
        weight[sub] = np.linalg.inv(covariance[sub])
    return weight


def ground_covariance(lon: ArrayLike, lat: ArrayLike, sigma_enu: ArrayLike,
                      frame_rotation: np.ndarray | None = None) -> np.ndarray:
    """(N, 3, 3) covariance of ground points whose sigmas are given along local east, north
    and up at each point, metres squared.

    Parameters
    ----------
    lon, lat : array_like, (N,)
        Degrees.
    sigma_enu : array_like, (N, 3)
        Standard deviations along east, north, up at each point, metres.
    frame_rotation : ndarray, (3, 3), optional
        ECEF -> frame rotation (e.g. :attr:`geoblock.coords.LocalFrame.rotation`); default
        the covariance is in ECEF.
    """
    r_pt = coords.enu_rotation(lon, lat)  # (N, 3, 3) ECEF -> ENU at the point
    rot = np.swapaxes(r_pt, -1, -2)  # ENU at the point -> ECEF
    if frame_rotation is not None:
        rot = frame_rotation @ rot
    sig = np.asarray(sigma_enu, dtype=np.float64)
    return rot @ (sig[:, :, None] ** 2 * np.eye(3)) @ np.swapaxes(rot, -1, -2)


def undetermined(matrix: np.ndarray, names: Sequence[str], tolerance: float = 1e-9, *,
                 design: bool = False) -> tuple[tuple[str, ...], int]:
    """The unknowns a least-squares problem cannot determine.

    Parameters
    ----------
    matrix : ndarray
        The normal matrix (K, K), or with ``design=True`` the (weighted) design matrix
        (N, K), whose singular values are used directly (more accurate: no squaring).
    names : sequence of str, (K,)
    tolerance : float
        Relative threshold of the eigenvalues (normal matrix) or singular values (design)
        below which a direction counts as singular, after the columns are scaled to unit
        norm (unit diagonal).
    design : bool

    Returns
    -------
    names : tuple of str
        The unknowns taking part (component above 0.1) in a singular direction, and those
        nothing depends on.
    directions : int
        Number of singular directions.
    """
    if design:
        d = np.linalg.norm(matrix, axis=0)
    else:
        d = np.sqrt(np.abs(np.diag(matrix)))
    zero = d == 0
    d = np.where(zero, 1.0, d)
    if design:
        _, w, vt = np.linalg.svd(matrix / d, full_matrices=False)
        vec = vt.T
    else:
        w, vec = np.linalg.eigh(matrix / np.outer(d, d))
    small = w < tolerance * max(float(np.max(w)), 1e-300)
    involved = zero.copy()
    if small.any():
        involved |= np.max(np.abs(vec[:, small]), axis=1) > 0.1
    return tuple(n for n, z in zip(names, involved, strict=True) if z), int(small.sum())
