"""What a block adjustment returns: :class:`BlockResult` and its per-image, per-measurement and
per-point parts."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.adjust.statistics import (
    AccuracyStats,
    IctpDiscrepancies,
    PointErrors,
)
from geoblock.models.protocol import SensorModel
from geoblock.typing import (
    BoolArray,
    Float64Array,
    IndexArray,
    StrArray,
)

if TYPE_CHECKING:
    from geoblock.adjust.accuracy import AccuracyStatement

__all__ = ["BlockResult", "HeightControlResults", "MeasurementResults", "ParameterEstimates",
           "PointResults", "SourceShift", "VerticalCheck"]


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
class SourceShift:
    """The estimated error common to the control points of one source (a reference
    orthoimage's misregistration), along local east, north and up at the source's centroid.

    Attributes
    ----------
    source : str
        The ground points' ``source``.
    solution : str
        ``"block"``, or in single mode the image whose solution estimated it.
    values : ndarray, (3,)
        Estimated shift e, n, h, metres: the source's coordinates minus the truth the block
        sees (0 on an axis without a shift sigma).
    sigmas : ndarray, (3,)
        Posterior standard deviations, metres (0 on such an axis).
    prior_sigmas : ndarray, (3,)
        ``sigma_shift_e, _n, _h``, metres.
    covariance : ndarray, (3, 3)
        Posterior covariance, square metres.
    lon, lat, h : float
        The source's centroid (degrees, metres), where its east/north/up axes are taken.
    n_points : int
        Its control points in the solution.
    """

    source: str
    solution: str
    values: Float64Array
    sigmas: Float64Array
    prior_sigmas: Float64Array
    covariance: Float64Array
    lon: float
    lat: float
    h: float
    n_points: int


@dataclass(frozen=True, eq=False)
class HeightControlResults:
    """The height control points (kind ``hcp``) of an adjustment, arrays (H,).

    ``observed`` their height (metres above the ellipsoid), ``adjusted`` the adjusted tie
    point's, ``residual = observed - adjusted``, ``sigma`` the a-priori ``sigma_h`` and
    ``posterior_sigma`` the adjusted height's posterior sigma (metres); ``source`` as in the
    ground points.
    """

    id: StrArray
    source: StrArray
    observed: Float64Array
    adjusted: Float64Array
    sigma: Float64Array
    posterior_sigma: Float64Array

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @property
    def residual(self) -> Float64Array:
        """(H,) observed minus adjusted height, metres."""
        return self.observed - self.adjusted

    def stats(self) -> dict[str, float | int]:
        """``n``, ``rmse``, ``mean``, ``max`` (signed, largest magnitude) and
        ``rms_normalised`` (RMS of residual / sigma) of the finite residuals, metres."""
        r = self.residual
        ok = np.isfinite(r)
        r, sig = r[ok], self.sigma[ok]
        if r.size == 0:
            nan = float("nan")
            return {"n": 0, "rmse": nan, "mean": nan, "max": nan, "rms_normalised": nan}
        return {"n": int(r.size), "rmse": float(np.sqrt(np.mean(r**2))),
                "mean": float(np.mean(r)), "max": float(r[np.argmax(np.abs(r))]),
                "rms_normalised": float(np.sqrt(np.mean((r / sig) ** 2)))}


@dataclass(frozen=True, eq=False)
class VerticalCheck:
    """ICPs measured in two images or more, intersected through the adjusted models
    (:func:`geoblock.triangulation.triangulate`), arrays (L,).

    ``e, n, u`` the intersected point minus the surveyed one, metres along local east, north,
    up (NaN where the intersection failed); ``covariance`` (L, 3, 3) its predicted
    covariance (first-order propagation of the image noise and of the parameters' posterior
    covariance, plus the survey's sigmas); ``rays`` the images intersected; ``status`` the
    triangulation's.
    """

    id: StrArray
    rays: Any
    e: Float64Array
    n: Float64Array
    u: Float64Array
    covariance: Float64Array
    status: Any

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @property
    def sigma_up(self) -> Float64Array:
        """(L,) predicted vertical sigma, metres."""
        return np.sqrt(self.covariance[:, 2, 2])


@dataclass(frozen=True, eq=False)
class BlockResult:
    """Outcome of :func:`adjust`.

    Attributes
    ----------
    models : dict of str to SensorModel
        The adjusted model of every image.
    parameters : dict of str to ParameterEstimates
    covariance : ndarray, (K, K)
        Posterior covariance of all adjusted parameters, in the order of ``parameter_index``
        (with ``adjust(covariance="none" | [ids])``, or ``"auto"`` above DENSE_LIMIT
        parameters: of the computed ones only, a note says so).
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
    predicted_covariance : ndarray, (N, 2, 2)
        For the rows of ``check``: the full predicted east/north covariance of the error
        (``predicted_sigma`` is the square root of its diagonal), square metres.
    check_source : ndarray of str, (N,)
        For the rows of ``check``: the ground point's ``source``.
    shifts : dict of str to SourceShift
        The common error estimated for each source with a shift sigma, by source (single
        mode: ``"<source> @ <image>"``).
    hcp : HeightControlResults or None
        The height control points in the solution.
    vertical : VerticalCheck or None
        ICPs measured in two images or more, intersected: the vertical accuracy.
    grid_covariance : dict of str to ndarray, (G, 2, 2)
        Per image (with a DEM), the predicted east/north covariance of the ground points of
        a 9 x 9 grid of image points on the DEM: the adjusted parameters' posterior and the
        DEM's sigma propagated to the ground (no image-measurement term): the accuracy
        statement without check points.
    solver : str
        How the reduced normal equations of the final linearisation were solved (dense
        Cholesky, sparse direct, conjugate gradients: the solver's own statement; one per
        solution when they differ), as ``adjust(..., solver=)`` chose.
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
    predicted_covariance: Float64Array | None = None
    check_source: StrArray | None = None
    shifts: dict[str, SourceShift] = field(default_factory=dict)
    hcp: HeightControlResults | None = None
    vertical: VerticalCheck | None = None
    grid_covariance: dict[str, Float64Array] = field(default_factory=dict)
    solver: str = ""

    def parameter_covariance(self, image: str) -> tuple[tuple[str, ...], Float64Array]:
        """The posterior covariance of one image's adjusted parameters.

        Parameters
        ----------
        image : str
            An image of :attr:`models`.

        Returns
        -------
        names : tuple of str, (K,)
            The image's adjusted parameters (rows of :attr:`parameter_index` for ``image``;
            empty when it was held fixed).
        covariance : ndarray, (K, K)
            :attr:`covariance` restricted to them, in their units squared: what
            ``model.correction_curves(covariance, names)`` and
            :func:`~geoblock.models.linescan.attitude_correction` take.

        Raises
        ------
        KeyError
            ``image`` is not in the block.
        """
        if image not in self.models:
            raise KeyError(f"BlockResult.parameter_covariance: no image {image!r} in the "
                           f"block (images: {list(self.models)})")
        idx = np.array([k for k, (i, _) in enumerate(self.parameter_index) if i == image],
                       dtype=np.intp)
        names = tuple(self.parameter_index[k][1] for k in idx)
        if not idx.size and image in self.parameters and self.parameters[image].names:
            # adjusted, its covariance not computed (adjust(covariance=...)): NaN
            n = len(self.parameters[image].names)
            return self.parameters[image].names, np.full((n, n), np.nan)
        cov = np.asarray(self.covariance, dtype=np.float64)
        return names, cov[np.ix_(idx, idx)] if idx.size else np.zeros((0, 0))

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

    def stats_by_source(self, kind: str, image: str | None = None,
                        ) -> dict[str, AccuracyStats]:
        """:meth:`stats` per ground-point ``source`` (``"survey"``, ``"reference:<file>"``
        ...), over every image or one."""
        sources = self._check_sources()
        out: dict[str, AccuracyStats] = {}
        rows = self.check.kind == kind.upper()
        if image is not None:
            rows &= self.check.image == image
        for source in dict.fromkeys(sources[rows].tolist()):
            sel = rows & (sources == source)
            out[str(source)] = AccuracyStats.from_errors(self.check.e[sel], self.check.n[sel])
        return out

    def _check_sources(self) -> StrArray:
        if self.check_source is None or len(self.check_source) != len(self.check):
            return np.full(len(self.check), "survey")
        return np.asarray(self.check_source).astype(str)

    def accuracy_statement(self, image: str | None = None) -> AccuracyStatement:
        """CE90/CE95/LE90 predicted from the posterior covariance beside the empirical figures
        at the ICPs, of one image or (None) of the block.

        CE: over the ICP measurements (of ``image``): :func:`~geoblock.adjust.accuracy.
        predicted_ce` of their predicted east/north covariances, the 90th/95th percentile of
        their radial errors and the NSSDA figure from their RMSE. LE90: over the ICPs measured
        in two images or more (one of them ``image``), intersected through the adjusted
        models (:attr:`vertical`); NaN with :attr:`AccuracyStatement.reason` when there is
        none. ``ce90_grid``/``ce95_grid``: over :attr:`grid_covariance` (no ICP needed).

        Raises
        ------
        KeyError
            ``image`` is not in the block.
        """
        from geoblock.adjust.accuracy import accuracy_statement

        if image is not None and image not in self.models:
            raise KeyError(f"BlockResult.accuracy_statement: no image {image!r} in the block "
                           f"(images: {list(self.models)})")
        rows = self.check.kind == "ICP"
        if image is not None:
            rows &= self.check.image == image
        cov = (self.predicted_covariance if self.predicted_covariance is not None
               else self.predicted_sigma[:, :, None] ** 2 * np.eye(2))
        du = sig = np.empty(0)
        v = self.vertical
        if v is not None and len(v):
            mine = np.ones(len(v), bool)
            if image is not None:
                m = self.measurements
                mine = np.isin(v.id, m.id[(m.image == image) & (m.kind == "icp")])
            du, sig = v.u[mine], v.sigma_up[mine]
        grid = [c for i, c in self.grid_covariance.items() if image is None or i == image]
        return accuracy_statement(self.check.e[rows], self.check.n[rows], cov[rows], du, sig,
                                  image=image, grid_covariance=np.concatenate(grid)
                                  if grid else np.empty((0, 2, 2)))

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
        if self.solver:
            lines.append(f"solver: {self.solver}")
        lines.extend(f"note: {n}" for n in self.notes)
        return "\n".join(lines)
