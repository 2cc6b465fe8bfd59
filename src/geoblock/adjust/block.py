"""DEM-aided block adjustment of any sensor models (Teo et al. 2010; Chen, Teo & Lo 2008).

One engine for every method. A :class:`Block` holds the images' models (each with the
parameter set to adjust: a model preset such as ``mba`` or ``dg``, or an
:class:`~geoblock.models.ImageCorrection` wrapper for RPCV-0/RPCV-1), the surveyed ground
points (GCPs, ICPs), the image measurements (GCP, ICP, TP, ICTP) and a DEM.
:func:`adjust` estimates, by Gauss-Newton with Levenberg-Marquardt damping on the sparse
normal equations reduced over the ground points (:mod:`geoblock.adjust.normal`):

* the adjustable parameters of every image, with their a-priori sigmas as
  pseudo-observations (Teo et al.'s modified bundle adjustment);
* the ground coordinates of every GCP (surveyed values as observations with their sigmas)
  and TP (weak pseudo-observations, ``tp_sigma_factor`` times the GCPs' sigma), in a local
  east-north-up frame at the block's centroid;

from the image measurements (sigma 0.5 px by default). The DEM controls the TPs' heights
(Teo et al. Figs. 1-2), either as the papers do (``dem_control="iterate"``: each iteration
re-interpolates the height from the DEM at the new planimetric position) or as a weighted
observation ``h - DEM(E, N) = 0`` with the DEM slope in its Jacobian and the DEM's sigma
(``"observation"``, the default). ICPs and ICTPs never enter the solution; they are
evaluated afterwards (:class:`BlockResult`).

Robust estimation: Huber or Cauchy re-weighting of the image measurements, or data
snooping; every measurement gets an externally studentised test statistic (leave-one-out,
chi-square with 2 degrees of freedom) and is flagged as a blunder above the ``alpha``
quantile. A measurement flagged in a point measured by two images only cannot be told from
its partner (both rays carry the same residual), so both are flagged and the point is
marked ``ambiguous``.

The engine never asks which model it holds: it uses ``project_with_status``,
``partials_parameters``, ``partials_ground``, ``parameters`` and ``with_parameters`` only.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.stats
from numpy.typing import NDArray

from geoblock import coords
from geoblock.adjust.normal import NormalSystem, SingularPoints, measurement_pairs
from geoblock.adjust.observations import GroundPoints, ImagePoints, lookup
from geoblock.adjust.statistics import (
    AccuracyStats,
    IctpDiscrepancies,
    PointErrors,
    ictp_accuracy,
)
from geoblock.adjust.weights import (
    check_measured_geometry,
    check_not_degenerate,
    ground_covariance,
    prior_weight,
    undetermined,
)
from geoblock.errors import (
    AdjustmentError,
    ObservationError,
    SingularSystemError,
    TooFewPointsError,
)
from geoblock.models.protocol import SensorModel
from geoblock.typing import (
    BoolArray,
    Float64Array,
    IndexArray,
    Status,
    StatusArray,
    StrArray,
)

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource

__all__ = [
    "DEM_CONTROLS",
    "MODES",
    "ROBUST",
    "TP_PRIORS",
    "Block",
    "BlockResult",
    "adjust",
    "check_errors",
]

MODES = ("block", "single")
"""``block``: all images together with GCPs, TPs and DEM control; ``single``: each image
alone with its own GCPs (no TPs, no DEM), as the papers' single adjustment."""
DEM_CONTROLS = ("observation", "iterate", "none")
"""How the DEM controls TP heights (module docstring)."""
ROBUST = ("none", "huber", "cauchy", "snooping")
"""Robust estimators of the image measurements."""
TP_PRIORS = ("floating", "fixed")
"""Centring of the TPs' weak ground pseudo-observations (:func:`adjust`)."""

#: GCP sigmas below this (metres) are raised to it: a sigma of 0 means "error-free" and
#: would give an infinite weight
MIN_GROUND_SIGMA_M = 1e-3
#: converged also when the cost changes by less than this fraction in an iteration
COST_TOLERANCE = 1e-10
#: sigma (metres) of the floating TP pseudo-observations after the first iteration: they only
#: keep a point regular where nothing else determines it (parallel rays without a DEM)
FLOATING_TP_SIGMA_M = 1e4
#: sigma (metres) holding a TP's height on the DEM surface in ``dem_control="iterate"``
ITERATE_HOLD_SIGMA_M = 1e-3


# ================================================================================ problem
@dataclass(frozen=True, eq=False)
class Block:
    """A block of images to adjust together.

    Parameters
    ----------
    models : mapping of str to SensorModel
        Image id -> model. Each model's ``parameters`` (values, a-priori sigmas, adjustable
        mask) say what is adjusted: choose them with ``model.with_parameter_set(name)`` or
        wrap the model in :class:`~geoblock.models.ImageCorrection`.
    measurements : ImagePoints
        Image measurements of every kind.
    ground : GroundPoints, optional
        Surveyed GCPs and ICPs.
    dem : DemSource, optional
        Terrain heights above the ellipsoid (:func:`geoblock.open_dem`): elevation control
        of the TPs and the initial TP positions.
    dem_sigma_m : float
        Standard deviation of the DEM's heights, metres (default 5 m).
    sigmas : mapping of str to mapping of str to float, optional
        Per image, a-priori sigmas overriding the model's for named parameters (``inf``: free;
        0: held fixed), in each parameter's unit.

    Raises
    ------
    ObservationError
        A measurement names an image that is not in ``models``, a GCP/ICP measurement has no
        ground point (or the other way round), or the block has no image.
    """

    models: Mapping[str, SensorModel]
    measurements: ImagePoints
    ground: GroundPoints | None = None
    dem: DemSource | None = None
    dem_sigma_m: float = 5.0
    sigmas: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        models = dict(self.models)
        if not models:
            raise ObservationError("block: no image")
        for image, table in self.sigmas.items():
            if image not in models:
                raise ObservationError(f"block: sigmas given for image {image!r}, which is not "
                                       f"in the block (images: {list(models)})")
            names = models[image].parameters.names
            for name, value in table.items():
                if name not in names:
                    raise ObservationError(
                        f"block: sigmas of image {image!r}: model {models[image].name!r} has no "
                        f"parameter {name!r}; its parameters are {list(names)}")
                if not (isinstance(value, int | float) and value >= 0):
                    raise ObservationError(f"block: sigmas of image {image!r}: {name} must be a "
                                           f"number >= 0 (inf: free), got {value!r}")
        unknown = ~np.isin(self.measurements.image, list(models))
        if unknown.any():
            pairs = sorted({f"{p} in {i!r}" for p, i in zip(
                self.measurements.id[unknown][:5].tolist(),
                self.measurements.image[unknown][:5].tolist(), strict=True)})
            raise ObservationError(
                f"block: measurement(s) of point(s) {', '.join(pairs)} name an image that is "
                f"not in the block (images: {list(models)})")
        if not (isinstance(self.dem_sigma_m, int | float) and self.dem_sigma_m > 0
                and math.isfinite(self.dem_sigma_m)):
            raise ObservationError(f"block: dem_sigma_m must be a finite number > 0, got "
                                   f"{self.dem_sigma_m!r}")
        object.__setattr__(self, "models", models)
        object.__setattr__(self, "measurements", self.measurements.resolve_kinds(self.ground))

    @property
    def image_ids(self) -> tuple[str, ...]:
        return tuple(self.models)


# ================================================================================ results
@dataclass(frozen=True, eq=False)
class ParameterEstimates:
    """Adjusted parameters of one image.

    ``names`` (K,), ``values`` and ``prior`` (K,) in each parameter's unit, ``sigmas`` (K,)
    posterior standard deviations, ``prior_sigmas`` (K,), ``units`` (K,).
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    prior: Float64Array
    values: Float64Array
    prior_sigmas: Float64Array
    sigmas: Float64Array


@dataclass(frozen=True, eq=False)
class MeasurementResults:
    """One row per image measurement of the block (every kind), arrays (M,).

    Attributes
    ----------
    id, image, kind : ndarray of str
    row, col : ndarray
        Measured, pixels.
    v_row, v_col : ndarray
        Residuals, observed minus computed with the adjusted models, pixels (ICPs: at the
        surveyed ground point; ICTPs: NaN).
    weight : ndarray
        Robust weight factor of the last iteration (0: rejected; NaN: not in the solution).
    redundancy_row, redundancy_col : ndarray
        Redundancy numbers (the diagonal of ``I - W J Q J^T``), NaN outside the solution.
    test : ndarray
        Externally studentised test statistic (chi-square, 2 degrees of freedom).
    flagged : ndarray of bool
        Blunder flag.
    ambiguous : ndarray of bool
        Flagged in a point with two rays only: it cannot be told from its partner.
    """

    id: StrArray
    image: StrArray
    kind: StrArray
    row: Float64Array
    col: Float64Array
    v_row: Float64Array
    v_col: Float64Array
    weight: Float64Array
    redundancy_row: Float64Array
    redundancy_col: Float64Array
    test: Float64Array
    flagged: BoolArray
    ambiguous: BoolArray


@dataclass(frozen=True, eq=False)
class PointResults:
    """One row per ground point in the solution (GCPs and TPs), arrays (J,).

    ``lon, lat, h``: adjusted (degrees, metres above the ellipsoid); ``covariance`` (J, 3, 3)
    posterior covariance along local east, north, up at the point (square metres);
    ``images`` the number of images measuring it; ``dem_height`` the DEM under the adjusted
    point (NaN without a DEM), ``status`` ``ok``, ``no-dem`` or ``failed`` (a projection
    failed in the last iteration).
    """

    id: StrArray
    kind: StrArray
    lon: Float64Array
    lat: Float64Array
    h: Float64Array
    covariance: Float64Array
    images: IndexArray
    dem_height: Float64Array
    status: StrArray

    @property
    def sigma_enu(self) -> Float64Array:
        """(J, 3) posterior standard deviations along east, north, up, metres."""
        return np.sqrt(np.einsum("jii->ji", self.covariance))


@dataclass(frozen=True, eq=False)
class BlockResult:
    """Outcome of :func:`adjust`.

    Attributes
    ----------
    models : dict of str to SensorModel
        The adjusted model of every image.
    parameters : dict of str to ParameterEstimates
    covariance : ndarray, (K, K)
        Posterior covariance of all adjusted parameters, in the order of ``parameter_index``.
    parameter_index : list of (str, str)
        ``(image, parameter name)`` of each row of ``covariance``.
    points : PointResults
    measurements : MeasurementResults
    check : PointErrors
        Per measurement of GCPs and ICPs: the measured image point located on the surface at
        the point's surveyed height through the adjusted model, minus the surveyed point
        (metres east/north), with the image residuals.
    predicted_sigma : ndarray, (N, 2)
        For the rows of ``check``: the standard deviation of that error along east and north
        that the posterior covariance predicts (parameters, image measurement, survey).
    ictp : IctpDiscrepancies or None
        ICTP relative accuracy through the adjusted models and the DEM.
    sigma0 : float
        Posterior standard deviation of unit weight.
    dof : int
    converged : bool
    iterations : int
    history : list of dict
        Per iteration: cost, sigma0, step size, damping, measurements rejected.
    mode, dem_control, robust : str
    notes : list of str
        What the user should know (assumed values, dropped points ...).
    """

    models: dict[str, SensorModel]
    parameters: dict[str, ParameterEstimates]
    covariance: Float64Array
    parameter_index: list[tuple[str, str]]
    points: PointResults
    measurements: MeasurementResults
    check: PointErrors
    predicted_sigma: Float64Array
    ictp: IctpDiscrepancies | None
    sigma0: float
    dof: int
    converged: bool
    iterations: int
    history: list[dict[str, Any]] = field(repr=False)
    mode: str = "block"
    dem_control: str = "observation"
    robust: str = "none"
    notes: list[str] = field(default_factory=list)

    # ---- statistics
    def stats(self, kind: str, image: str | None = None) -> AccuracyStats:
        """Ground accuracy (metres) at ``gcp`` or ``icp`` measurements, of one image or all."""
        sel = self.check.select(kind=kind, image=image)
        return sel.stats()

    def stats_by_image(self, kind: str) -> dict[str, AccuracyStats]:
        """:meth:`stats` per image (images that have such points)."""
        out: dict[str, AccuracyStats] = {}
        for image in self.models:
            sel = self.check.select(kind=kind, image=image)
            if len(sel):
                out[image] = sel.stats()
        return out

    def ictp_by_pair(self) -> dict[tuple[str, str], AccuracyStats]:
        """ICTP discrepancy statistics per pair of images (Teo et al.'s relative accuracy)."""
        return {} if self.ictp is None else self.ictp.by_pair()

    def report_text(self) -> str:
        """A plain-text summary: convergence, sigma0, GCP/ICP/ICTP tables."""
        lines = [f"block adjustment ({self.mode}, DEM control {self.dem_control}, robust "
                 f"{self.robust}): {'converged' if self.converged else 'NOT converged'} in "
                 f"{self.iterations} iterations, sigma0 {self.sigma0:.4g}, dof {self.dof}"]
        for kind in ("gcp", "icp"):
            for image, st in self.stats_by_image(kind).items():
                lines.append(f"{kind.upper():4s} {image:12s} {st.as_row()}")
        for (a, b), st in self.ictp_by_pair().items():
            lines.append(f"ICTP {a} & {b}: {st.as_row()}")
        flagged = int(self.measurements.flagged.sum())
        if flagged:
            lines.append(f"{flagged} measurement(s) flagged as blunders")
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)


# ================================================================================ engine
@dataclass
class _Setup:
    """Everything fixed during a solution."""

    ids: tuple[str, ...]
    models: list[SensorModel]
    adj: list[IndexArray]  # per image, the indices of its adjustable parameters
    gidx: IndexArray  # (images, max adjustable): position of each in the parameter vector
    n_params: int
    prior_x: Float64Array  # (K,) a-priori values of the adjustable parameters
    prior_w: Float64Array  # (K, K) prior weight
    # measurements in the solution
    m_sel: IndexArray  # indices into block.measurements
    image_of: IndexArray
    point_of: IndexArray
    obs: Float64Array  # (M, 2)
    sigma: Float64Array  # (M, 2)
    # points in the solution
    p_id: StrArray
    p_kind: StrArray
    frame: coords.LocalFrame
    x0: Float64Array  # (J, 3) initial local coordinates
    g_center: Float64Array  # (J, 3) centre of the ground pseudo-observation
    g_weight: Float64Array  # (J, 3, 3)
    dem_rows: BoolArray  # (J,) bool: TP under DEM control
    n_images: IndexArray  # (J,) images measuring the point


@dataclass
class _DemRows:
    """DEM observation rows of the points in the solution, NaN (gradient 0) where none."""

    grad: Float64Array  # (J, 3) d(h - DEM)/d(local coordinates)
    misclosure: Float64Array  # (J,) observed 0 minus computed h - DEM, metres
    sigma: Float64Array  # (J,) metres
    dem_h: Float64Array  # (J,) DEM height under the point, metres


@dataclass
class _Evaluation:
    """Residuals and cost at one estimate (:meth:`_Engine.evaluate`)."""

    models: list[SensorModel]
    v: Float64Array  # (M, 2) observed minus computed, pixels
    vw: Float64Array  # (M, 2) whitened by the a-priori sigmas, 0 where not projected
    status: StatusArray  # (M,)
    ok: BoolArray  # (M,) projected
    lon: Float64Array  # (J,)
    lat: Float64Array
    h: Float64Array
    dem: _DemRows
    pts: Float64Array  # (J, 3) local coordinates
    cost_fixed: float  # parameter and DEM terms
    cost: float = math.nan


@dataclass
class _Statistics:
    """Cofactors, redundancy numbers and test statistics of a solution."""

    q_pp: Float64Array  # (K, K)
    q_xx: Float64Array  # (J, 3, 3)
    q_px: Any  # the parameter-point cofactor blocks, as NormalSystem.point_cofactors gives
    test: Float64Array  # (M,)
    redundancy: Float64Array  # (M, 2)


@dataclass
class _Solution:
    """What :meth:`_Engine.run` found."""

    x: Float64Array
    pts: Float64Array
    ev: _Evaluation
    system: NormalSystem
    converged: bool
    iterations: int
    history: list[dict[str, Any]]
    threshold: float


def _params_vector(models: list[SensorModel], adj: list[IndexArray], gidx: IndexArray,
                   k: int) -> Float64Array:
    x = np.zeros(k)
    for i, m in enumerate(models):
        x[gidx[i, : adj[i].size]] = m.parameters.values[adj[i]]
    return x


def _with_params(models: list[SensorModel], adj: list[IndexArray], gidx: IndexArray,
                 x: Float64Array) -> list[SensorModel]:
    out = []
    for i, m in enumerate(models):
        values = np.array(m.parameters.values)
        values[adj[i]] = x[gidx[i, : adj[i].size]]
        out.append(m.with_parameters(values) if adj[i].size else m)
    return out


def _prior(model: SensorModel, overrides: Mapping[str, float]) -> tuple[BoolArray, Float64Array]:
    """Adjustable mask (P,) and a-priori covariance (P, P) of a model's parameters, with
    sigma overrides by name (0: fixed; inf: free)."""
    params = model.parameters
    mask = np.array(params.adjustable, dtype=bool)
    cov = np.array(params.prior_covariance, dtype=np.float64)
    for name, sigma in overrides.items():
        k = params.index(name)
        if sigma == 0:
            mask[k] = False
            continue
        cov[k, :] = 0.0
        cov[:, k] = 0.0
        cov[k, k] = float(sigma) ** 2
        mask[k] = True
    return mask, cov


def _local_to_enu_rotation(frame: coords.LocalFrame, lon: Float64Array,
                           lat: Float64Array) -> Float64Array:
    """(J, 3, 3) rotation from the local frame to ENU at each point."""
    return coords.enu_rotation(lon, lat) @ frame.rotation.T


def _dem_height(dem: DemSource, lon: Float64Array, lat: Float64Array) -> Float64Array:
    """DEM heights above the ellipsoid, metres; NaN where the DEM has none."""
    h, status = dem.height_with_status(lon, lat)
    return np.where(status == Status.CONVERGED, np.asarray(h, dtype=np.float64), np.nan)


def _names(ids: StrArray, limit: int = 8) -> str:
    names = [str(i) for i in np.asarray(ids).tolist()]
    return ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit
                                       else "")


class _Engine:
    """One Gauss-Newton / Levenberg-Marquardt solution of a block (or of one image)."""

    def __init__(self, block: Block, ids: tuple[str, ...], *, use_tps: bool,
                 dem_control: str, tp_sigma_factor: float, tp_sigma_m: float | None,
                 tp_prior: str, notes: list[str]) -> None:
        self.block = block
        self.tp_prior = tp_prior
        self.tp_sigma_m_first = FLOATING_TP_SIGMA_M
        self.dem_control = dem_control if block.dem is not None else "none"
        self.notes = notes
        meas = block.measurements
        models = [block.models[i] for i in ids]
        priors = [_prior(m, block.sigmas.get(i, {})) for i, m in zip(ids, models, strict=True)]
        adj = [np.flatnonzero(mask) for mask, _ in priors]
        self.priors = priors
        sizes = np.array([a.size for a in adj])
        kmax = max(int(sizes.max()), 1)
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        gidx = np.full((len(ids), kmax), -1, np.intp)
        for i, (o, s) in enumerate(zip(offsets, sizes, strict=True)):
            gidx[i, :s] = o + np.arange(s)
        k = int(sizes.sum())
        prior_w = np.zeros((k, k))
        for i in range(len(models)):
            sl = slice(offsets[i], offsets[i] + sizes[i])
            prior_w[sl, sl] = prior_weight(priors[i][1][np.ix_(adj[i], adj[i])])
        prior_x = _params_vector(models, adj, gidx, k)

        kinds = ("gcp", "tp") if use_tps else ("gcp",)
        sel = np.flatnonzero(np.isin(meas.image, ids) & np.isin(meas.kind, kinds))
        # points in the solution
        p_id, point_of = np.unique(meas.id[sel], return_inverse=True)
        image_of = lookup(np.array(ids), meas.image[sel])
        n_images = np.bincount(point_of, minlength=p_id.size)
        p_kind = np.empty(p_id.size, dtype="<U4")
        p_kind[point_of] = meas.kind[sel]
        self.setup_checks(ids, models, adj, sizes, meas, sel, p_id, p_kind, n_images, priors)

        ground = block.ground
        gk = lookup(ground.id, p_id) if ground is not None else np.full(p_id.size, -1)
        is_gcp = p_kind == "gcp"
        lon0 = np.full(p_id.size, np.nan)
        lat0 = np.full(p_id.size, np.nan)
        h0 = np.full(p_id.size, np.nan)
        sig = np.full((p_id.size, 3), np.nan)
        if is_gcp.any():
            assert ground is not None  # GCP kinds come from the ground points
            g = gk[is_gcp]
            lon0[is_gcp], lat0[is_gcp], h0[is_gcp] = ground.lon[g], ground.lat[g], ground.h[g]
            sig[is_gcp] = np.maximum(
                np.stack([ground.sigma_e[g], ground.sigma_n[g], ground.sigma_h[g]], -1),
                MIN_GROUND_SIGMA_M)
        is_tp = ~is_gcp
        if is_tp.any():
            lon0[is_tp], lat0[is_tp], h0[is_tp] = self._initial_tps(
                models, ids, meas, sel, point_of, np.flatnonzero(is_tp))
            if tp_sigma_m is None:
                base = (np.median(sig[is_gcp], axis=0) if is_gcp.any() else np.full(3, 3.0))
                tp_sig = tp_sigma_factor * np.maximum(base, 1.0)
            else:
                tp_sig = np.full(3, float(tp_sigma_m))
            sig[is_tp] = tp_sig
            self.tp_sigma_m_first = float(np.max(tp_sig))
        frame = coords.LocalFrame.centred_on(lon0, lat0, h0)
        x0 = np.stack(frame.from_geodetic(lon0, lat0, h0), axis=-1)
        g_weight = np.asarray(np.linalg.inv(ground_covariance(lon0, lat0, sig, frame.rotation)),
                              dtype=np.float64)
        dem_rows = is_tp & (self.dem_control != "none")
        self.s = _Setup(
            ids=ids, models=models, adj=adj, gidx=gidx, n_params=k, prior_x=prior_x,
            prior_w=prior_w, m_sel=sel, image_of=image_of, point_of=point_of,
            obs=np.stack([meas.row[sel], meas.col[sel]], -1),
            sigma=np.stack([meas.sigma_row[sel], meas.sigma_col[sel]], -1),
            p_id=p_id, p_kind=p_kind, frame=frame, x0=x0, g_center=x0.copy(),
            g_weight=g_weight, dem_rows=dem_rows, n_images=n_images,
        )
        self.pairs = measurement_pairs(point_of, p_id.size)
        self.weight = np.ones(sel.size)  # robust weight factors

    # ------------------------------------------------------------------ checks
    def setup_checks(self, ids: tuple[str, ...], models: list[SensorModel],
                     adj: list[IndexArray], sizes: IndexArray, meas: ImagePoints,
                     sel: IndexArray, p_id: StrArray, p_kind: StrArray, n_images: IndexArray,
                     priors: list[tuple[BoolArray, Float64Array]]) -> None:
        if sel.size == 0:
            raise TooFewPointsError(
                f"block: no GCP{' or TP' if len(ids) > 1 else ''} measurement in image(s) "
                f"{', '.join(ids)}: nothing to adjust from")
        counts = np.bincount(lookup(np.array(ids), meas.image[sel]), minlength=len(ids))
        empty = [i for i, c, s in zip(ids, counts, sizes, strict=True) if c == 0 and s > 0]
        if empty:
            raise TooFewPointsError(
                f"block: image(s) {', '.join(empty)} have no GCP or TP measurement: their "
                "parameters cannot be adjusted (add points, or fix their parameters)")
        single = (p_kind == "tp") & (n_images < 2)
        if single.any():
            raise ObservationError(
                f"block: tie point(s) {_names(p_id[single])} are measured in one image only; "
                "a TP must be measured in two images or more (remove them or mark them ictp)")
        for i, image in enumerate(ids):
            prior = priors[i][1][np.ix_(adj[i], adj[i])]
            free = ~np.isfinite(np.diag(prior))
            n_obs = 2 * int(counts[i])
            if int(free.sum()) > n_obs:
                names = [models[i].parameters.names[a] for a in adj[i][free]]
                raise TooFewPointsError(
                    f"block: image {image!r} has {counts[i]} measurement(s) ({n_obs} "
                    f"observations) for {int(free.sum())} free parameter(s) "
                    f"({', '.join(names)}); add GCPs or TPs or give them a-priori sigmas")
            mine = sel[lookup(np.array(ids), meas.image[sel]) == i]
            check_measured_geometry(
                meas.id[mine], meas.row[mine], meas.col[mine],
                [f"{image}:{models[i].parameters.names[a]}" for a in adj[i][free]],
                f"block: image {image!r}")

    def _initial_tps(self, models: list[SensorModel], ids: tuple[str, ...], meas: ImagePoints,
                     sel: IndexArray, point_of: IndexArray, tp_points: IndexArray,
                     ) -> tuple[Float64Array, Float64Array, Float64Array]:
        """Initial TP positions: each ray localised on the DEM (or at the GCPs' mean
        height), averaged in ECEF; then put on the DEM."""
        from geoblock.dem.intersect import localize

        block = self.block
        want = np.isin(point_of, tp_points)
        m_idx = sel[want]
        xyz = np.full((m_idx.size, 3), np.nan)
        for i, image in enumerate(ids):
            mine = meas.image[m_idx] == image
            if not mine.any():
                continue
            rows, cols = meas.row[m_idx][mine], meas.col[m_idx][mine]
            if block.dem is not None:
                g, _ = localize(models[i], rows, cols, block.dem, warn=False)
            else:
                h_guess = (float(np.nanmean(block.ground.h))
                           if block.ground is not None and len(block.ground)
                           else float(np.mean(models[i].height_range)))
                g, _ = models[i].backproject_with_status(rows, cols,
                                                         np.full(rows.shape, h_guess))
            xyz[mine] = np.stack(coords.geodetic_to_ecef(*g), axis=-1)
        pts = point_of[want]
        sums = np.zeros((point_of.max() + 1, 3))
        cnt = np.zeros(point_of.max() + 1)
        ok = np.all(np.isfinite(xyz), axis=1)
        np.add.at(sums, pts[ok], xyz[ok])
        np.add.at(cnt, pts[ok], 1)
        failed = tp_points[cnt[tp_points] == 0]
        if failed.size:
            ids_failed = np.unique(meas.id[sel][np.isin(point_of, failed)])
            raise ObservationError(
                f"block: tie point(s) {_names(ids_failed)} could not be located in any image "
                "(their rays miss the DEM or the models' domains)")
        mean = sums[tp_points] / cnt[tp_points, None]
        lon, lat, h = coords.ecef_to_geodetic(mean[:, 0], mean[:, 1], mean[:, 2])
        lon, lat, h = np.asarray(lon), np.asarray(lat), np.asarray(h)
        if block.dem is not None:
            hd = _dem_height(block.dem, lon, lat)
            h = np.where(np.isfinite(hd), hd, h)
        return lon, lat, h

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, x: Float64Array, pts: Float64Array) -> _Evaluation:
        """Residuals and cost at parameters ``x`` (K,) and points ``pts`` (J, 3)."""
        s = self.s
        models = _with_params(s.models, s.adj, s.gidx, x)
        lon, lat, h = (np.asarray(a) for a in s.frame.to_geodetic(pts[:, 0], pts[:, 1],
                                                                  pts[:, 2]))
        computed = np.full(s.obs.shape, np.nan)
        status = np.zeros(s.obs.shape[0], np.uint8)
        for i, model in enumerate(models):
            mine = np.flatnonzero(s.image_of == i)
            if mine.size == 0:
                continue
            j = s.point_of[mine]
            (r, c), st = model.project_with_status(lon[j], lat[j], h[j])
            computed[mine, 0], computed[mine, 1] = r, c
            status[mine] = st
        v = s.obs - computed
        ok = status == Status.CONVERGED
        vw = np.where(ok[:, None], v / s.sigma, 0.0)
        dp = x - s.prior_x
        dem = self._dem_rows(lon, lat, h, pts)
        ev = _Evaluation(models=models, v=v, vw=vw, status=status, ok=ok, lon=lon, lat=lat, h=h,
                         dem=dem, pts=pts, cost_fixed=float(dp @ s.prior_w @ dp)
                         + float(np.nansum((dem.misclosure / dem.sigma) ** 2)))
        self.recost(ev)
        return ev

    def recost(self, ev: _Evaluation) -> None:
        """``ev.cost`` again after the robust weights or the ground pseudo-observations
        changed (no projection)."""
        s = self.s
        dg = ev.pts - s.g_center
        ev.cost = (float(np.sum(self.weight[:, None] * ev.vw ** 2)) + ev.cost_fixed
                   + float(np.einsum("ji,jik,jk->", dg, s.g_weight, dg)))

    def _dem_rows(self, lon: Float64Array, lat: Float64Array, h: Float64Array,
                  pts: Float64Array) -> _DemRows:
        """DEM observation rows of the TPs: gradient (J, 3), misclosure (J,) (observed 0
        minus computed ``h - DEM``), sigma (J,); NaN where there is none."""
        s = self.s
        n = pts.shape[0]
        grad = np.zeros((n, 3))
        mis = np.full(n, np.nan)
        sigma = np.full(n, np.nan)
        rows = np.flatnonzero(s.dem_rows)
        if rows.size == 0:
            return _DemRows(grad=grad, misclosure=mis, sigma=sigma, dem_h=mis.copy())
        dem = self.block.dem
        assert dem is not None  # dem_rows is empty without a DEM
        hd = _dem_height(dem, lon[rows], lat[rows])
        if self.dem_control == "iterate":
            up = _local_to_enu_rotation(s.frame, lon[rows], lat[rows])[:, 2, :]  # d h / d local
            grad[rows] = up
            mis[rows] = np.where(np.isfinite(hd), 0.0, np.nan)
            sigma[rows] = ITERATE_HOLD_SIGMA_M
        else:
            step = max(1.0, 0.5 * float(getattr(dem, "resolution_m", 2.0)))
            p = pts[rows]
            offs = np.concatenate([np.eye(3), -np.eye(3)]) * step  # (6, 3)
            q = (p[None, :, :] + offs[:, None, :]).reshape(-1, 3)
            g = s.frame.to_geodetic(q[:, 0], q[:, 1], q[:, 2])
            fq = (np.asarray(g.h) - _dem_height(dem, np.asarray(g.lon), np.asarray(g.lat)))
            fq = fq.reshape(6, rows.size)
            grad[rows] = ((fq[:3] - fq[3:]) / (2 * step)).T
            mis[rows] = -(h[rows] - hd)
            sigma[rows] = self.block.dem_sigma_m
        bad = ~np.isfinite(mis) | ~np.all(np.isfinite(grad), axis=1)
        mis[bad] = np.nan
        grad[bad] = 0.0
        dem_h = np.full(n, np.nan)
        dem_h[rows] = hd
        return _DemRows(grad=grad, misclosure=mis, sigma=sigma, dem_h=dem_h)

    # ------------------------------------------------------------------ linearisation
    def linearize(self, x: Float64Array, pts: Float64Array, ev: _Evaluation) -> NormalSystem:
        s = self.s
        m_count = s.obs.shape[0]
        kmax = s.gidx.shape[1]
        a = np.zeros((m_count, 2, kmax))
        b = np.zeros((m_count, 2, 3))
        rot_t = s.frame.rotation.T  # d ECEF / d local
        for i, model in enumerate(ev.models):
            mine = np.flatnonzero(s.image_of == i)
            if mine.size == 0:
                continue
            j = s.point_of[mine]
            lon, lat, h = ev.lon[j], ev.lat[j], ev.h[j]
            if s.adj[i].size:
                a[mine, :, : s.adj[i].size] = model.partials_parameters(lon, lat, h)[
                    ..., s.adj[i]]
            b[mine] = model.partials_ground(lon, lat, h) @ rot_t
        ok = ev.ok[:, None, None]
        # whitened by the a-priori sigmas (kept for the statistics), then by the robust weights
        a = np.where(ok, np.nan_to_num(a / s.sigma[:, :, None]), 0.0)
        b = np.where(ok, np.nan_to_num(b / s.sigma[:, :, None]), 0.0)
        self.prior_whitened = (a, b)
        w = np.sqrt(self.weight)[:, None, None]
        a, b = a * w, b * w
        vw = ev.vw * np.sqrt(self.weight)[:, None]
        dem = ev.dem
        has = np.isfinite(dem.misclosure)
        dw = np.where(has, 1.0 / np.where(has, dem.sigma, 1.0) ** 2, 0.0)
        n_extra = s.g_weight + dw[:, None, None] * dem.grad[:, :, None] * dem.grad[:, None]
        b_extra = (np.einsum("jik,jk->ji", s.g_weight, s.g_center - pts)
                   + (dw * np.where(has, dem.misclosure, 0.0))[:, None] * dem.grad)
        return NormalSystem(
            n_params=s.n_params, gidx=s.gidx, image_of=s.image_of, point_of=s.point_of,
            a=a, b=b, v=vw, n_pp_prior=s.prior_w, b_p_prior=s.prior_w @ (s.prior_x - x),
            n_xx_extra=n_extra, b_x_extra=b_extra, pairs=self.pairs,
        )

    # ------------------------------------------------------------------ diagnosis
    def diagnose(self, system: NormalSystem, exc: Exception) -> SingularSystemError:
        s = self.s
        if isinstance(exc, SingularPoints):
            ids = s.p_id[exc.points]
            return SingularSystemError(
                f"block: the ground coordinates of point(s) {_names(ids)} cannot be determined "
                "(their rays are parallel and no DEM or ground observation fixes them)",
                tuple(str(i) for i in ids))
        reduced = getattr(system, "reduced", None)
        if reduced is None:
            return SingularSystemError(f"block: singular normal equations ({exc})", ())
        if hasattr(reduced, "toarray"):
            reduced = reduced.toarray()
        labels = [""] * s.n_params
        for i, image in enumerate(s.ids):
            for kk, a in enumerate(s.adj[i]):
                labels[s.gidx[i, kk]] = f"{image}:{s.models[i].parameters.names[a]}"
        names, directions = undetermined(reduced, labels)
        return SingularSystemError(
            f"block: the observations cannot determine parameter(s) {', '.join(names[:12])}"
            f"{' ...' if len(names) > 12 else ''} ({directions} singular direction(s)); "
            "add or spread GCPs/TPs in those images, or give these parameters a-priori sigmas",
            tuple(names))

    # ------------------------------------------------------------------ solution
    def run(self, *, max_iterations: int, tolerance: float, robust: str, robust_k: float,
            alpha: float, label: str, progress: Callable[[str], None]) -> _Solution:
        s = self.s
        x = s.prior_x.copy()
        pts = s.x0.copy()
        history: list[dict[str, Any]] = []
        ev = self.evaluate(x, pts)
        self._check_status(ev)
        lam = 0.0
        converged = False
        robust_started = False
        rounds = 0
        threshold = float(scipy.stats.chi2.ppf(1.0 - alpha, 2))
        system = None
        it = 0
        cap = max_iterations + (20 if robust != "none" else 0)
        while it < cap:
            it += 1
            system = self.linearize(x, pts, ev)
            accepted = False
            for _ in range(12):
                try:
                    dp, dx = system.solve(lam)
                except np.linalg.LinAlgError as exc:
                    raise self.diagnose(system, exc) from None
                x_new, pts_new = x + dp, pts + dx
                if self.dem_control == "iterate":
                    pts_new = self._onto_dem(pts_new)
                ev_new = self.evaluate(x_new, pts_new)
                bad = ~ev_new.ok & ev.ok
                if (ev_new.cost <= ev.cost * (1 + 1e-9) + 1e-12 and not bad.any()) or \
                        self.dem_control == "iterate" and not bad.any():
                    accepted = True
                    break
                lam = max(1e-4, lam * 10.0)
            if not accepted:
                raise AdjustmentError(
                    f"{label}: no Levenberg-Marquardt step reduces the cost (damping "
                    f"{lam:.3g}); the block is too far from its solution or ill-posed")
            # step size in a-priori-cofactor sigmas of the undamped system
            sig_p = np.sqrt(_inverse_diag_estimate(system))
            sig_x = np.sqrt(np.maximum(np.einsum("jii->ji", system.c), 1e-300))
            # the change actually made (dem_control="iterate" puts the heights back on the DEM)
            step = max(float(np.max(np.abs(x_new - x) / sig_p, initial=0.0)),
                       float(np.max(np.abs(pts_new - pts) / sig_x, initial=0.0)))
            rel = (ev.cost - ev_new.cost) / max(ev.cost, 1e-300)
            x, pts, ev = x_new, pts_new, ev_new
            if self.tp_prior == "floating":
                # re-centred on the estimate, and released after the first step: a damping
                # of the first step from the on-board positions, never a pull on the solution
                tp = s.p_kind == "tp"
                s.g_center[tp] = pts[tp]
                if it == 1:
                    s.g_weight[tp] *= (self.tp_sigma_m_first / FLOATING_TP_SIGMA_M) ** 2
                self.recost(ev)
            lam = lam / 10.0 if lam > 1e-7 else 0.0
            n_obs = self._n_obs(ev)
            dof = n_obs - s.n_params - 3 * s.p_id.size
            sigma0 = math.sqrt(ev.cost / dof) if dof > 0 else float("nan")
            history.append({"iteration": it, "cost": ev.cost, "sigma0": sigma0,
                            "max_step_sigma": step, "damping": lam,
                            "rejected": int(np.sum(self.weight == 0)),
                            "downweighted": int(np.sum(self.weight < 0.5))})
            progress(f"{label}: iteration {it:2d}  sigma0 {sigma0:10.4g}  max step "
                     f"{step:9.3g} sigma  rejected {history[-1]['rejected']}")
            small = step < tolerance or abs(rel) < COST_TOLERANCE
            # robust phase: once least squares has converged, re-weight at every iteration
            # (IRLS; data snooping only at convergence) until the weights settle
            if robust != "none" and rounds < 20 and (small or (robust_started
                                                              and robust != "snooping")):
                robust_started = True
                changed = self._reweight(ev, system, robust, robust_k, threshold)
                rounds += 1
                if changed:
                    self.recost(ev)
                    continue
            if small:
                converged = True
                break
        for i, image in enumerate(s.ids):
            mine = np.flatnonzero(s.image_of == i)
            if mine.size and s.adj[i].size:
                j = s.point_of[mine]
                check_not_degenerate(s.models[i], ev.models[i], ev.lon[j], ev.lat[j],
                                     ev.h[j], f"{label}: image {image!r}")
        system = self.linearize(x, pts, ev)
        try:
            system.solve(0.0)
        except np.linalg.LinAlgError as exc:
            raise self.diagnose(system, exc) from None
        return _Solution(x=x, pts=pts, ev=ev, system=system, converged=converged,
                         iterations=it, history=history, threshold=threshold)

    def _onto_dem(self, pts: Float64Array) -> Float64Array:
        """``dem_control="iterate"``: the TPs' heights re-interpolated from the DEM."""
        s = self.s
        rows = np.flatnonzero(s.dem_rows)
        if rows.size == 0:
            return pts
        g = s.frame.to_geodetic(pts[rows, 0], pts[rows, 1], pts[rows, 2])
        lon, lat = np.asarray(g.lon), np.asarray(g.lat)
        assert self.block.dem is not None  # dem_rows is empty without a DEM
        hd = _dem_height(self.block.dem, lon, lat)
        h = np.where(np.isfinite(hd), hd, np.asarray(g.h))
        out = pts.copy()
        out[rows] = np.stack(s.frame.from_geodetic(lon, lat, h), axis=-1)
        return out

    def _n_obs(self, ev: _Evaluation) -> int:
        s = self.s
        img = 2 * int(np.sum(ev.ok & (self.weight > 0)))
        prior = int(np.sum(np.diag(s.prior_w) > 0))
        dem = int(np.sum(np.isfinite(ev.dem.misclosure)))
        ground = s.p_id.size if self.tp_prior == "fixed" else int(np.sum(s.p_kind == "gcp"))
        return img + prior + 3 * ground + dem

    def _check_status(self, ev: _Evaluation) -> None:
        s = self.s
        bad = ~ev.ok
        if bad.any():
            meas = self.block.measurements
            idx = s.m_sel[bad]
            listed = ", ".join(f"{p} in {i}" for p, i in zip(
                meas.id[idx][:8].tolist(), meas.image[idx][:8].tolist(), strict=True))
            raise AdjustmentError(
                f"block: the models cannot project {int(bad.sum())} measured point(s) "
                f"({listed}); check their coordinates and heights against the models' domains")
        # a GCP that projects more than an image away from its measurement through the
        # unadjusted model is a wrong coordinate or a wrong image, not an adjustable error
        size = np.array([max(m.shape) for m in s.models], dtype=np.float64)[s.image_of]
        far = (s.p_kind[s.point_of] == "gcp") & (np.hypot(ev.v[:, 0], ev.v[:, 1]) > size)
        if far.any():
            meas = self.block.measurements
            idx = s.m_sel[far]
            listed = ", ".join(f"{p} in {i} ({d:.3g} px)" for p, i, d in zip(
                meas.id[idx][:8].tolist(), meas.image[idx][:8].tolist(),
                np.hypot(ev.v[far, 0], ev.v[far, 1])[:8].tolist(), strict=True))
            raise ObservationError(
                f"block: {int(far.sum())} GCP measurement(s) lie more than an image size from "
                f"where the unadjusted model projects their ground point: {listed}; check "
                "their ground coordinates, image ids and measurements")

    def statistics(self, ev: _Evaluation, system: NormalSystem) -> _Statistics:
        """Per-measurement hat blocks, redundancy and leave-one-out test statistics."""
        q_pp = system.parameter_cofactor()
        q_xx, q_px = system.point_cofactors(q_pp)
        s = self.s
        w = np.where(ev.ok, self.weight, 0.0)
        # D = J Q J^T / sigma^2 (a-priori whitening), every measurement, rejected ones too
        d = system.hat_blocks(q_pp, q_xx, q_px, *self.prior_whitened)
        eye = np.eye(2)
        i_wd = eye - w[:, None, None] * d
        u = np.where(ev.ok[:, None], ev.v / s.sigma, np.nan)  # a-priori whitened
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_iwd = np.linalg.inv(i_wd)
            v_loo = np.einsum("mij,mj->mi", inv_iwd, u)
            d_loo = d + w[:, None, None] * d @ inv_iwd @ d
            test = np.einsum("mi,mij,mj->m", v_loo, np.linalg.inv(eye + d_loo), v_loo)
        redundancy = np.einsum("mii->mi", i_wd)
        return _Statistics(q_pp=q_pp, q_xx=q_xx, q_px=q_px, test=test, redundancy=redundancy)

    def _reweight(self, ev: _Evaluation, system: NormalSystem, robust: str, k: float,
                  threshold: float) -> bool:
        """Update the robust weights; True if they changed enough to iterate again."""
        s = self.s
        old = self.weight.copy()
        if robust == "snooping":
            st = self.statistics(ev, system)
            test = np.where(self.weight > 0, st.test, -np.inf)
            over = test > threshold
            if not over.any():
                return False
            # the largest per point only (a blunder spreads into the point's other rays)
            best = np.full(s.p_id.size, -np.inf)
            np.maximum.at(best, s.point_of, test)
            reject = over & (test >= best[s.point_of])
            self.weight[reject] = 0.0
            return True
        e = np.sqrt(np.sum(np.where(ev.ok[:, None], ev.vw, 0.0) ** 2, axis=1))
        used = ev.ok
        scale = max(1.0, float(np.median(e[used])) / math.sqrt(2 * math.log(2)))
        t = e / scale
        if robust == "huber":
            w = np.where(t <= k, 1.0, k / np.maximum(t, 1e-300))
        else:  # cauchy
            w = 1.0 / (1.0 + (t / k) ** 2)
        self.weight = w
        return bool(np.max(np.abs(w - old)) > 1e-2)


def _inverse_diag_estimate(system: NormalSystem) -> Float64Array:
    """(K,) ``1 / diag(S)`` of the reduced system: a cheap lower bound of the parameters'
    cofactor variances, good enough to scale the convergence test."""
    reduced = system.reduced
    diag = reduced.diagonal() if hasattr(reduced, "diagonal") else np.diag(reduced)
    return 1.0 / np.maximum(np.asarray(diag, dtype=np.float64), 1e-300)


# ================================================================================ driver
def adjust(
    block: Block,
    *,
    mode: str = "block",
    dem_control: str = "observation",
    tp_sigma_factor: float = 10.0,
    tp_sigma_m: float | None = None,
    tp_prior: str = "floating",
    robust: str = "none",
    robust_k: float = 2.5,
    alpha: float = 0.001,
    collocation: bool | Mapping[str, Any] = False,
    max_iterations: int = 30,
    tolerance: float = 1e-4,
    progress: Callable[[str], None] | None = None,
) -> BlockResult:
    """Adjust a block (module docstring).

    Parameters
    ----------
    block : Block
    mode : {"block", "single"}
        ``block``: all images together with GCPs, TPs and the DEM; ``single``: each image
        alone with its GCPs (TPs and DEM unused), as the papers' single adjustment.
    dem_control : {"observation", "iterate", "none"}
        DEM elevation control of the TPs (ignored without a DEM or in ``single`` mode).
    tp_sigma_factor : float
        TP ground pseudo-observations' sigma, as a multiple of the GCPs' median sigma per
        axis (at least 1 m; Teo et al.: 10).
    tp_sigma_m : float, optional
        The TPs' sigma in metres, instead of ``tp_sigma_factor``.
    tp_prior : {"floating", "fixed"}
        Where the TPs' ground pseudo-observations are centred. ``"fixed"``: at the initial
        positions ray-traced through the unadjusted models, as Teo et al. write it; with
        on-board errors of tens of metres this pulls the block toward the on-board
        positions (a bias that grows with the number of TPs). ``"floating"`` (default):
        they damp the first step from the on-board positions, then are re-centred on the
        estimate at every iteration and released to a sigma of
        :data:`FLOATING_TP_SIGMA_M` (they only keep a point regular where nothing else
        determines it), so they never bias the solution nor slow its convergence; they are
        not counted as observations in the degrees of freedom.
    robust : {"none", "huber", "cauchy", "snooping"}
        Robust estimation of the image measurements (after a first least-squares
        solution): Huber's or Cauchy's re-weighting with constant ``robust_k`` (in units
        of the measurement sigmas, scaled up by a robust sigma0 when that exceeds 1), or
        data snooping (the measurement with the largest test statistic above the threshold
        in each point is rejected, and the block solved again, until none is left).
    robust_k : float
        Constant of the Huber and Cauchy weight functions.
    alpha : float
        Significance level of the blunder test (chi-square, 2 degrees of freedom;
        0.001 gives 13.8).
    collocation : bool or mapping
        Least-squares collocation of each image's residual vectors after the adjustment
        (Teo et al. eqs. 4-5): ``True`` or the options of
        :func:`geoblock.adjust.collocation.fit_collocation` (``filtering_ratio``,
        ``d_max``). The adjusted models are then wrapped in
        :class:`~geoblock.adjust.collocation.CollocationCorrection`.
    max_iterations : int
        Iteration cap of Gauss-Newton (robust re-weighting adds up to 20).
    tolerance : float
        Converged when every step is below ``tolerance`` a-priori standard deviations of
        its unknown (dimensionless), or the cost no longer decreases.
    progress : callable, optional
        Called with one line per iteration.

    Returns
    -------
    BlockResult

    Raises
    ------
    ObservationError, TooFewPointsError, SingularSystemError
        Before or while solving: a TP seen by one image, an image with no point, fewer
        observations than free parameters, parameters or points the observations cannot
        determine (the message names the images, points and parameters).
    AdjustmentError
        A measured point the models cannot project, or no step reducing the cost.
    """
    if mode not in MODES:
        raise AdjustmentError(f"adjust: mode must be one of {MODES}, got {mode!r}")
    if dem_control not in DEM_CONTROLS:
        raise AdjustmentError(f"adjust: dem_control must be one of {DEM_CONTROLS}, got "
                              f"{dem_control!r}")
    if tp_prior not in TP_PRIORS:
        raise AdjustmentError(f"adjust: tp_prior must be one of {TP_PRIORS}, got {tp_prior!r}")
    if robust not in ROBUST:
        raise AdjustmentError(f"adjust: robust must be one of {ROBUST}, got {robust!r}")
    for name, value in (("tp_sigma_factor", tp_sigma_factor), ("robust_k", robust_k),
                        ("tolerance", tolerance)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise AdjustmentError(f"adjust: {name} must be a finite number > 0, got {value!r}")
    if not 0 < alpha < 1:
        raise AdjustmentError(f"adjust: alpha must be in (0, 1), got {alpha!r}")
    if tp_sigma_m is not None and not (math.isfinite(tp_sigma_m) and tp_sigma_m > 0):
        raise AdjustmentError(f"adjust: tp_sigma_m must be > 0, got {tp_sigma_m!r}")
    say = progress or (lambda message: None)
    notes: list[str] = []
    start = time.perf_counter()
    ids = block.image_ids
    if mode == "block":
        groups = [ids]
        if block.dem is None and dem_control != "none":
            notes.append("no DEM: the TP heights are not controlled")
    else:
        groups = [(i,) for i in ids]
    solutions: list[tuple[_Engine, _Solution, _Statistics]] = []
    for group in groups:
        engine = _Engine(block, group, use_tps=mode == "block",
                         dem_control=dem_control if mode == "block" else "none",
                         tp_sigma_factor=tp_sigma_factor, tp_sigma_m=tp_sigma_m,
                         tp_prior=tp_prior, notes=notes)
        label = "block" if mode == "block" else f"single {group[0]}"
        out = engine.run(max_iterations=max_iterations, tolerance=tolerance, robust=robust,
                         robust_k=robust_k, alpha=alpha, label=label, progress=say)
        solutions.append((engine, out, engine.statistics(out.ev, out.system)))
    result = _assemble(block, solutions, mode=mode, dem_control=dem_control, robust=robust,
                       collocation=collocation, notes=notes)
    say(f"adjusted in {time.perf_counter() - start:.2f} s: sigma0 {result.sigma0:.4g}, "
        f"{'converged' if result.converged else 'NOT converged'}")
    return result


def _assemble(block: Block, solutions: list[tuple[_Engine, _Solution, _Statistics]], *,
              mode: str, dem_control: str, robust: str,
              collocation: bool | Mapping[str, Any], notes: list[str]) -> BlockResult:
    meas = block.measurements
    n_meas = len(meas)
    models: dict[str, SensorModel] = {}
    parameters: dict[str, ParameterEstimates] = {}
    cov_blocks: list[Float64Array] = []
    index: list[tuple[str, str]] = []
    v = np.full((n_meas, 2), np.nan)
    weight = np.full(n_meas, np.nan)
    red = np.full((n_meas, 2), np.nan)
    test = np.full(n_meas, np.nan)
    point_parts: list[dict[str, NDArray[Any]]] = []
    cost = 0.0
    dof = 0
    converged = True
    iterations = 0
    history: list[dict[str, Any]] = []
    q_by_image: dict[str, tuple[IndexArray, Float64Array]] = {}
    threshold = np.inf
    for engine, out, st in solutions:
        s = engine.s
        ev = out.ev
        n_obs = engine._n_obs(ev)
        dof_k = n_obs - s.n_params - 3 * s.p_id.size
        cost += ev.cost
        dof += dof_k
        converged &= out.converged
        iterations = max(iterations, out.iterations)
        history.extend(out.history)
        threshold = out.threshold
        sigma0_k = math.sqrt(ev.cost / dof_k) if dof_k > 0 else float("nan")
        var0 = sigma0_k**2 if dof_k > 0 else 1.0
        for i, image in enumerate(s.ids):
            model = ev.models[i]
            models[image] = model
            g = s.gidx[i, : s.adj[i].size]
            q = st.q_pp[np.ix_(g, g)] * var0
            q_by_image[image] = (s.adj[i], q)
            names = tuple(model.parameters.names[a] for a in s.adj[i])
            parameters[image] = ParameterEstimates(
                names=names, units=tuple(model.parameters.units[a] for a in s.adj[i]),
                prior=np.array(s.models[i].parameters.values[s.adj[i]]),
                values=np.array(model.parameters.values[s.adj[i]]),
                prior_sigmas=np.sqrt(np.diag(engine.priors[i][1])[s.adj[i]]),
                sigmas=np.sqrt(np.diag(q)))
            cov_blocks.append(q)
            index.extend((image, n) for n in names)
        v[s.m_sel] = ev.v
        weight[s.m_sel] = np.where(ev.ok, engine.weight, 0.0)
        red[s.m_sel] = st.redundancy
        test[s.m_sel] = st.test / max(1.0, sigma0_k if np.isfinite(sigma0_k) else 1.0) ** 2
        rot = _local_to_enu_rotation(s.frame, ev.lon, ev.lat)
        cov_enu = rot @ (st.q_xx * var0) @ np.swapaxes(rot, 1, 2)
        status = np.full(s.p_id.size, "ok", dtype="<U8")
        status[s.dem_rows & ~np.isfinite(ev.dem.misclosure)] = "no-dem"
        failed = np.zeros(s.p_id.size, bool)
        failed[s.point_of[~ev.ok]] = True
        status[failed] = "failed"
        dem_h = (_dem_height(block.dem, ev.lon, ev.lat) if block.dem is not None
                 else np.full(s.p_id.size, np.nan))
        point_parts.append({"id": s.p_id, "kind": s.p_kind, "lon": ev.lon, "lat": ev.lat,
                            "h": ev.h, "cov": cov_enu, "images": s.n_images, "dem": dem_h,
                            "status": status})
    k = sum(b.shape[0] for b in cov_blocks)
    covariance = np.zeros((k, k))
    o = 0
    for b in cov_blocks:
        covariance[o:o + b.shape[0], o:o + b.shape[0]] = b
        o += b.shape[0]
    if mode == "block":  # one solution: the full covariance, cross-image terms included
        dof_k = dof
        var0 = cost / dof if dof > 0 else 1.0
        covariance = solutions[0][2].q_pp * var0
    sigma0 = math.sqrt(cost / dof) if dof > 0 else float("nan")

    # blunder flags
    flagged = np.isfinite(test) & (test > threshold)
    ambiguous = np.zeros(n_meas, bool)
    if flagged.any():
        # a TP in the solution with two rays, one of them flagged: both, ambiguous
        in_solution = np.isfinite(weight) & (meas.kind == "tp")
        ids, point = np.unique(meas.id, return_inverse=True)
        rays = np.bincount(point, weights=in_solution, minlength=ids.size)
        hit = np.bincount(point, weights=flagged & in_solution, minlength=ids.size) > 0
        pair = in_solution & (rays[point] == 2) & hit[point]
        ambiguous[pair] = True
        flagged[pair] = True
        notes.append(f"{int(flagged.sum())} measurement(s) flagged as blunders (test > "
                     f"{threshold:.3g}, chi-square 2 dof)")

    adjusted = dict(models)  # before collocation: their parameters are the covariance's
    # collocation of the residual vectors
    if collocation:
        from geoblock.adjust.collocation import CollocationCorrection, fit_collocation

        options = dict(collocation) if isinstance(collocation, Mapping) else {}
        for image in list(models):
            use = (meas.image == image) & np.isfinite(weight) & (weight > 0) & ~flagged
            if use.sum() < 3:
                notes.append(f"collocation: image {image} has {int(use.sum())} residual "
                             "vectors, fewer than 3: not applied")
                continue
            col = fit_collocation(meas.row[use], meas.col[use], v[use, 0], v[use, 1], **options)
            models[image] = CollocationCorrection(models[image], col)

    check, predicted, v_check = _check_points(block, models, q_by_image, sigma0, adjusted)
    icp_rows = np.isin(meas.kind, ("icp",))
    v[icp_rows] = v_check[icp_rows]
    ictp = None
    sel = meas.kind == "ictp"
    if sel.any():
        if block.dem is not None:
            ictp = ictp_accuracy(models, meas.id[sel], meas.image[sel], meas.row[sel],
                                 meas.col[sel], block.dem, warn=False)
        else:
            notes.append("no DEM: ICTP relative accuracy not computed")
    # one row per point (single mode: a GCP seen by several images is taken from the first)
    cat = {k: np.concatenate([part[k] for part in point_parts]) for k in point_parts[0]}
    _, first = np.unique(cat["id"], return_index=True)
    first = np.sort(first)
    points = PointResults(
        id=cat["id"][first].astype(str), kind=cat["kind"][first].astype(str),
        lon=cat["lon"][first], lat=cat["lat"][first], h=cat["h"][first],
        covariance=cat["cov"][first].reshape(-1, 3, 3),
        images=cat["images"][first].astype(np.intp), dem_height=cat["dem"][first],
        status=cat["status"][first].astype(str))
    measurements = MeasurementResults(
        id=meas.id, image=meas.image, kind=meas.kind, row=meas.row, col=meas.col,
        v_row=v[:, 0], v_col=v[:, 1], weight=weight, redundancy_row=red[:, 0],
        redundancy_col=red[:, 1], test=test, flagged=flagged, ambiguous=ambiguous)
    return BlockResult(
        models=models, parameters=parameters, covariance=covariance, parameter_index=index,
        points=points, measurements=measurements, check=check, predicted_sigma=predicted,
        ictp=ictp, sigma0=sigma0, dof=dof, converged=bool(converged), iterations=iterations,
        history=history, mode=mode, dem_control=dem_control if mode == "block" else "none",
        robust=robust, notes=notes)


def check_errors(block: Block, models: Mapping[str, SensorModel] | None = None) -> PointErrors:
    """Ground errors at the block's GCP and ICP measurements through some models.

    Each measured image point is located on the surface at its ground point's surveyed
    height through its image's model and compared with the surveyed point (metres east and
    north), as :attr:`BlockResult.check` does for the adjusted models: to evaluate any set of
    models on a block (the unadjusted ones, a reference, ...).

    Parameters
    ----------
    block : Block
    models : mapping of str to SensorModel, optional
        Default ``block.models``.
    """
    return _check_points(block, dict(block.models if models is None else models), {}, 1.0)[0]


def _check_points(block: Block, models: Mapping[str, SensorModel],
                  q_by_image: Mapping[str, tuple[IndexArray, Float64Array]], sigma0: float,
                  adjusted: Mapping[str, SensorModel] | None = None,
                  ) -> tuple[PointErrors, Float64Array, Float64Array]:
    """GCP/ICP ground errors per measurement through ``models``, their sigmas predicted
    through ``adjusted`` (the models whose parameters ``q_by_image`` gives, per image, the
    adjusted indices and their covariance of; default ``models``), image residuals."""
    adjusted = models if adjusted is None else adjusted
    meas = block.measurements
    n = len(meas)
    v = np.full((n, 2), np.nan)
    ground = block.ground
    sel = np.flatnonzero(np.isin(meas.kind, ("gcp", "icp")))
    if ground is None or sel.size == 0:
        empty = np.empty(0)
        return PointErrors(np.empty(0, str), np.empty(0, str), empty, empty), \
            np.empty((0, 2)), v
    g = lookup(ground.id, meas.id[sel])
    lon, lat, h = ground.lon[g], ground.lat[g], ground.h[g]
    e = np.full(sel.size, np.nan)
    nn = np.full(sel.size, np.nan)
    pred = np.full((sel.size, 2), np.nan)
    for image, model in models.items():
        mine = np.flatnonzero(meas.image[sel] == image)
        if mine.size == 0:
            continue
        m = sel[mine]
        (r, c), _ = model.project_with_status(lon[mine], lat[mine], h[mine])
        v[m, 0] = meas.row[m] - r
        v[m, 1] = meas.col[m] - c
        (lo, la, hh), _ = model.backproject_with_status(meas.row[m], meas.col[m], h[mine])
        de, dn, _ = coords.enu_offsets(lon[mine], lat[mine], h[mine], lo, la, hh)
        e[mine], nn[mine] = de, dn
        # predicted covariance of the located point's E, N
        model = adjusted[image]
        jg = model.partials_ground(lon[mine], lat[mine], h[mine]) @ np.swapaxes(
            coords.enu_rotation(lon[mine], lat[mine]), 1, 2)  # d(r,c)/d(e,n,u) at the point
        m_inv = np.linalg.inv(jg[:, :, :2])
        cov_img = np.zeros((mine.size, 2, 2))
        cov_img[:, 0, 0] = meas.sigma_row[m] ** 2
        cov_img[:, 1, 1] = meas.sigma_col[m] ** 2
        adjustable, q = q_by_image.get(image, (np.zeros(0, np.intp), np.zeros((0, 0))))
        if q.size:
            a = model.partials_parameters(lon[mine], lat[mine], h[mine])[..., adjustable]
            cov_img = cov_img + a @ q @ np.swapaxes(a, 1, 2)
        up = jg[:, :, 2:3]
        cov_img = cov_img + up @ np.swapaxes(up, 1, 2) * (ground.sigma_h[g][mine] ** 2)[
            :, None, None]
        cov = m_inv @ cov_img @ np.swapaxes(m_inv, 1, 2)
        cov[:, 0, 0] += ground.sigma_e[g][mine] ** 2
        cov[:, 1, 1] += ground.sigma_n[g][mine] ** 2
        pred[mine] = np.sqrt(np.einsum("nii->ni", cov))
    check = PointErrors(meas.id[sel], meas.kind[sel], e, nn, None, v[sel, 0], v[sel, 1],
                        meas.image[sel])
    return check, pred, v
