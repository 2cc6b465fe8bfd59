"""Pieces the single-image resection and the block engine share: a-priori weights of
parameters and ground points, and the diagnosis of undetermined unknowns."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from geoblock import coords
from geoblock.typing import ArrayLike, BoolArray, Float64Array, StrArray

if TYPE_CHECKING:
    from geoblock.models.parameters import ParameterSet
    from geoblock.models.protocol import SensorModel

__all__ = ["check_measured_geometry", "check_not_degenerate", "ground_covariance",
           "parameter_prior", "prior_weight", "undetermined"]


def prior_weight(covariance: Float64Array) -> Float64Array:
    """(K, K) weight matrix of a-priori parameter values: the inverse of the covariance on the
    parameters whose sigma is finite, zero rows and columns for free (infinite-sigma) ones."""
    finite = np.isfinite(np.diag(covariance))
    weight = np.zeros_like(covariance, dtype=np.float64)
    if finite.any():
        sub = np.ix_(finite, finite)
        weight[sub] = np.linalg.inv(covariance[sub])
    return weight


def ground_covariance(lon: ArrayLike, lat: ArrayLike, sigma_enu: ArrayLike,
                      frame_rotation: Float64Array | None = None) -> Float64Array:
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


def undetermined(matrix: Float64Array, names: Sequence[str], tolerance: float = 1e-9, *,
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


#: measured image points closer together than this (pixels) are one point for the
#: geometry check of :func:`check_measured_geometry`
COINCIDENT_PX = 1.0
#: the measured image points are collinear when their spread across the line is below this
#: fraction of their spread along it (or below :data:`COINCIDENT_PX`)
COLLINEAR_RATIO = 1e-3


def check_measured_geometry(ids: Sequence[str] | StrArray, row: ArrayLike, col: ArrayLike,
                            free: Sequence[str], where: str) -> None:
    """Refuse control measurements whose image geometry cannot determine ``n_free`` free
    parameters: all at one pixel (only a shift can be determined), or on one line (an
    affinity cannot be determined).

    Parameters
    ----------
    ids : sequence of str, (N,)
        Named in the message.
    row, col : array_like, (N,)
        Measured image coordinates, pixels.
    free : sequence of str
        The adjustable parameters without an a-priori sigma (named in the message and in
        the error's ``undetermined``).
    where : str
        Prefix of the message (``"resect"``, ``"block: image 'x'"``).

    Raises
    ------
    SingularSystemError
        The measurements are coincident (and more than a shift, 2 parameters, is free) or
        collinear (and more than 3 parameters are free).
    """
    from geoblock.errors import SingularSystemError

    free = tuple(free)
    n_free = len(free)
    if n_free <= 2:
        return
    pts = np.stack([np.asarray(row, float), np.asarray(col, float)], axis=-1)
    if pts.shape[0] == 0:
        return
    centred = pts - pts.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False) if pts.shape[0] > 1 else np.zeros(2)
    s = np.concatenate([s, np.zeros(2 - s.size)])
    spread = s / np.sqrt(max(pts.shape[0], 1))  # RMS distance along each principal axis
    listed = ", ".join(str(i) for i in list(ids)[:8]) + (" ..." if len(ids) > 8 else "")
    if spread[0] < COINCIDENT_PX:
        raise SingularSystemError(
            f"{where}: the {pts.shape[0]} control measurement(s) ({listed}) all lie within "
            f"{COINCIDENT_PX:g} px of one image point: they can determine a shift, not "
            f"parameters {', '.join(free)}; measure points spread over the image", free)
    if n_free > 3 and (spread[1] < COLLINEAR_RATIO * spread[0] or spread[1] < COINCIDENT_PX):
        raise SingularSystemError(
            f"{where}: the {pts.shape[0]} control measurement(s) ({listed}) lie on one line in "
            f"the image (spread across it {spread[1]:.3g} px): they cannot determine "
            f"parameters {', '.join(free)}; add points off that line (an affine correction "
            "needs three that are not collinear)", free)


def check_not_degenerate(before: SensorModel, after: SensorModel, lon: ArrayLike, lat: ArrayLike,
                         h: ArrayLike, where: str, limit: float = 5.0) -> None:
    """Refuse an adjusted model that collapses or blows up the image geometry: the area
    scale of its ground -> image mapping (``|det d(row, col)/d(E, N)|`` at the control
    points) must stay within ``limit`` times the unadjusted model's.

    Raises
    ------
    AdjustmentError
        Naming ``where`` and the scale change (for example six GCPs all measured at one pixel,
        which an affinity "fits" by mapping the whole image onto that pixel).
    """
    from geoblock.errors import AdjustmentError

    def area(model: SensorModel) -> Float64Array:
        rot = coords.enu_rotation(lon, lat)  # ECEF -> ENU
        jac = model.partials_ground(lon, lat, h) @ np.swapaxes(rot, -1, -2)  # d(r,c)/d(e,n,u)
        return np.abs(np.linalg.det(jac[..., :2]))

    a0, a1 = area(before), area(after)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = float(np.nanmedian(a1 / a0))
    if not (1.0 / limit <= ratio <= limit):
        raise AdjustmentError(
            f"{where}: the adjusted model is degenerate: it scales image areas by {ratio:.3g} "
            "against the unadjusted model at the control points (the control measurements "
            "and their ground coordinates do not describe one image geometry); check them")


def parameter_prior(model: SensorModel, overrides: Mapping[str, float]
                    ) -> tuple[BoolArray, Float64Array]:
    """Adjustable mask (P,) and a-priori covariance (P, P) of a model's parameters, with
    sigma overrides by name (0: fixed; inf: free).

    An adjustment weights the adjustable parameters' pseudo-observations by
    :func:`prior_weight` of the covariance's adjustable block. When the set carries an
    a-priori ``information`` matrix (:class:`~geoblock.models.ParameterSet`: a smoothness
    prior, the ``"jitter"`` set), that block is the inverse of the information's adjustable
    block (the prior of the adjustable parameters given the fixed ones), so the weight is the
    information itself; an override replaces the parameter's row and column of the
    information by ``1 / sigma^2`` on the diagonal (0: free). Elsewhere the covariance is the
    information's inverse (:attr:`~geoblock.models.ParameterSet.prior_covariance`).
    """
    params = model.parameters
    mask = np.array(params.adjustable, dtype=bool)
    information = getattr(params, "information", None)
    if information is not None:
        return _information_prior(params, information, mask, overrides)
    cov = np.array(params.prior_covariance, dtype=np.float64)
    _override(params, mask, cov, overrides, lambda sigma: float(sigma) ** 2)
    return mask, cov


def _override(params: ParameterSet, mask: BoolArray, matrix: Float64Array,
              overrides: Mapping[str, float], diagonal: Callable[[float], float]) -> bool:
    """Apply sigma overrides in place: 0 fixes the parameter (``mask``); any other sigma
    makes it adjustable, uncorrelated, with ``diagonal(sigma)`` its entry of ``matrix`` (a
    covariance or an information). Whether any entry of ``matrix`` changed."""
    changed = False
    for name, sigma in overrides.items():
        k = params.index(name)
        if sigma == 0:
            mask[k] = False
            continue
        matrix[k, :] = 0.0
        matrix[:, k] = 0.0
        matrix[k, k] = diagonal(sigma)
        mask[k] = True
        changed = True
    return changed


def _information_prior(params: ParameterSet, information: Float64Array, mask: BoolArray,
                       overrides: Mapping[str, float]) -> tuple[BoolArray, Float64Array]:
    """:func:`parameter_prior` of a set with an a-priori information matrix."""
    from geoblock.models.parameters import covariance_from_information

    info = np.array(information, dtype=np.float64)
    changed = _override(params, mask, info, overrides,
                        lambda sigma: 0.0 if np.isinf(sigma) else 1.0 / float(sigma) ** 2)
    cov = (covariance_from_information(info, params.names) if changed
           else np.array(params.prior_covariance, dtype=np.float64))
    adj = np.flatnonzero(mask)
    if adj.size and not mask.all():
        # the adjustable parameters' prior given the fixed ones: its weight is the
        # information's adjustable block (a principal block: positive definite where the
        # whole is)
        cov[np.ix_(adj, adj)] = covariance_from_information(info[np.ix_(adj, adj)])
    return mask, cov
