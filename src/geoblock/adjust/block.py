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
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from geoblock import coords
from geoblock.adjust.observations import lookup
from geoblock.adjust.statistics import (
    PointErrors,
    ictp_accuracy,
)
from geoblock.errors import (
    AdjustmentError,
)
from geoblock.models.protocol import SensorModel
from geoblock.typing import (
    Float64Array,
    IndexArray,
)

if TYPE_CHECKING:
    pass

from geoblock.adjust._engine import (
    _dem_height,
    _Engine,
    _local_to_enu_rotation,
    _Solution,
    _Statistics,
)
from geoblock.adjust._islands import check_block
from geoblock.adjust._start import warm_start
from geoblock.adjust.normal import DENSE_LIMIT, SOLVERS, SelectedCofactor
from geoblock.adjust._consider import CONSIDER_STEP_M, consider_sources, has_source_shifts
from geoblock.adjust.problem import (
    CONTROL_SHIFTS,
    DEM_CONTROLS,
    MODES,
    ROBUST,
    TP_PRIORS,
    Block,
)
from geoblock.adjust.results import (
    BlockResult,
    HeightControlResults,
    MeasurementResults,
    ParameterEstimates,
    PointResults,
    SourceShift,
)

__all__ = [
    "DEM_CONTROLS",
    "MODES",
    "ROBUST",
    "TP_PRIORS",
    "Block",
    "BlockResult",
    "MeasurementResults",
    "ParameterEstimates",
    "PointResults",
    "adjust",
    "check_errors",
]


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
    control_shifts: str = "consider",
    components: str = "refuse",
    solver: str = "auto",
    covariance: str | Sequence[str] = "auto",
    start: Any = None,
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
        its unknown (dimensionless), or the cost no longer decreases, or the cost changes by
        less than :data:`~geoblock.adjust.problem.CREEP_COST_TOLERANCE` of itself and the
        step is below ``tolerance`` in the undamped normal matrix's metric (no unknown then
        moves by more than ``tolerance`` of its posterior sigma).
    control_shifts : {"consider", "estimate"}
        How the common error of a control source (the ground points' ``sigma_shift_*``, a
        reference orthoimage's misregistration) enters. ``"consider"`` (default): the block
        is registered to the sources as they are and their common errors are propagated
        into every posterior figure (one more adjustment per source and axis,
        :mod:`geoblock.adjust._consider`); the estimate cannot drift where nothing else
        sees absolute position. ``"estimate"``: three unknowns per source with that prior,
        for blocks where surveyed GCPs or other sources make them observable.
    components : {"refuse", "separate", "joint"}
        A block whose images form several groups that no GCP or tie point links
        (:mod:`geoblock.adjust._islands`, checked from the measurements alone before any
        projection): ``"refuse"`` (default) raises an AdjustmentError naming each group;
        ``"separate"`` adjusts each group alone (its own sigma0, iterations and statistics)
        and merges them into one result (``covariance`` block diagonal over the groups;
        ``sigma0`` pooled from the groups' costs and degrees of freedom); ``"joint"``
        solves them in one system as they are. A group that nothing anchors (no GCP, no
        DEM control, no a-priori sigmas on its parameters) is singular and refused as any
        such block is.
    solver : {"auto", "dense", "direct", "iterative"}
        How the reduced normal equations are solved (:class:`~geoblock.adjust.normal.
        NormalSystem`): dense Cholesky (up to :data:`~geoblock.adjust.normal.DENSE_LIMIT`
        parameters), a sparse direct factorisation, or conjugate gradients preconditioned
        by the images' blocks; ``"auto"`` chooses by size and memory.
        :attr:`BlockResult.solver` states what solved the final system.
    covariance : {"auto", "full", "none"} or sequence of str
        Which parameter cofactors the statistics compute after the solution: ``"full"``
        the dense ``Q_pp`` (a (K, K) array: 29 GB at 6 x 10^4 parameters); ``"none"``
        none; a sequence of image ids, those images' parameter columns only (solved from
        the factorisation, never the dense inverse). ``"auto"`` (default): full up to
        :data:`~geoblock.adjust.normal.DENSE_LIMIT` parameters, none above. What is not
        computed is NaN (parameter sigmas, point covariances, redundancy numbers, test
        statistics, predicted check-point sigmas) and a note says so;
        :attr:`BlockResult.covariance` then holds the computed columns only, in the order
        of :attr:`BlockResult.parameter_index`. ``robust="snooping"`` needs the full one
        (refused otherwise).
    start : BlockResult or path, optional
        Warm start (:mod:`geoblock.adjust._start`): a previous solution of (part of) the
        block, as a BlockResult or the output directory (or its ``report.json``) of
        ``geoblock adjust``. Its images start from their adjusted parameters and its points
        from their adjusted coordinates; the others from their on-board models and
        ray-traced positions. The answer is the cold start's (to ``tolerance``), in fewer
        iterations when little changed (images added to a solved block).
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
        Several disconnected groups of images (``components="refuse"``), a measured point
        the models cannot project, or no step reducing the cost.
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
    if isinstance(covariance, str):
        if covariance not in ("auto", "full", "none"):
            raise AdjustmentError("adjust: covariance must be 'auto', 'full', 'none' or a "
                                  f"sequence of image ids, got {covariance!r}")
        cov_option: str | tuple[str, ...] = covariance
    else:
        cov_option = tuple(str(c) for c in covariance)
        unknown = [c for c in cov_option if c not in block.models]
        if unknown:
            raise AdjustmentError(f"adjust: covariance names image(s) not in the block: "
                                  f"{', '.join(unknown[:8])}")
    warm = None if start is None else warm_start(start)
    if solver not in SOLVERS:
        raise AdjustmentError(f"adjust: solver must be one of {SOLVERS}, got {solver!r}")
    if control_shifts not in CONTROL_SHIFTS:
        raise AdjustmentError(f"adjust: control_shifts must be one of {CONTROL_SHIFTS}, got "
                              f"{control_shifts!r}")
    groups = (check_block(block, components) if mode == "block"
              else [(i,) for i in block.image_ids])
    if control_shifts == "consider" and has_source_shifts(block):
        if cov_option != "full" and cov_option != "auto":
            raise AdjustmentError("adjust: control_shifts='consider' propagates the sources' "
                                  "common errors through the full covariance: use "
                                  "covariance='full' or 'auto', or control_shifts='estimate'")
        options: dict[str, Any] = {"components": components, "solver": solver,
                                   "covariance": covariance, "start": warm,
            "mode": mode, "dem_control": dem_control, "tp_sigma_factor": tp_sigma_factor,
                   "tp_sigma_m": tp_sigma_m, "tp_prior": tp_prior, "robust": robust,
                   "robust_k": robust_k, "alpha": alpha, "collocation": collocation,
                   "max_iterations": max_iterations, "tolerance": tolerance,
                   "control_shifts": "estimate"}
        runs = iter(range(1_000_000))

        def run(b: Block) -> BlockResult:
            first = next(runs) == 0
            if not first and progress is not None:
                progress("considering the control sources' common errors: the block "
                         "adjusted again with a source's points moved by "
                         f"{CONSIDER_STEP_M:g} m")
            return adjust(b, **options, progress=progress if first else None)

        return consider_sources(block, run)
    say = progress or (lambda message: None)
    notes: list[str] = []
    start = time.perf_counter()
    if mode == "block":
        if len(groups) > 1:
            notes.append(f"{len(groups)} disconnected groups of images adjusted separately "
                         f"(components=\"separate\"): {', '.join(str(len(g)) for g in groups)}"
                         " images; no tie holds one group to another")
        if block.dem is None and dem_control != "none":
            notes.append("no DEM: the TP heights are not controlled")
    else:
        if np.any(block.measurements.kind == "hcp"):
            notes.append("single mode: height control points (tie points with a height) are "
                         "not used")
    solutions: list[tuple[_Engine, _Solution, _Statistics]] = []
    for group in groups:
        engine = _Engine(block, group, use_tps=mode == "block",
                         dem_control=dem_control if mode == "block" else "none",
                         tp_sigma_factor=tp_sigma_factor, tp_sigma_m=tp_sigma_m,
                         tp_prior=tp_prior, notes=notes, solver=solver,
                         covariance=cov_option, start=warm)
        label = ("block" if len(groups) == 1 else f"group {len(solutions) + 1}"
                 ) if mode == "block" else f"single {group[0]}"
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
    solution_cov: list[Float64Array] = []
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
    shifts: dict[str, SourceShift] = {}
    hcp_parts: list[tuple[Any, ...]] = []
    for engine, out, st in solutions:
        s = engine.s
        ev = out.ev
        sol_index: list[tuple[str, str]] = []  # (image, name) of each model parameter column
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
            q = _cofactor_block(st.q_pp, g) * var0
            q_by_image[image] = (s.adj[i], q)
            names = tuple(model.parameters.names[a] for a in s.adj[i])
            parameters[image] = ParameterEstimates(
                names=names, units=tuple(model.parameters.units[a] for a in s.adj[i]),
                prior=np.array(s.models[i].parameters.values[s.adj[i]]),
                values=np.array(model.parameters.values[s.adj[i]]),
                prior_sigmas=np.sqrt(np.diag(engine.priors[i][1])[s.adj[i]]),
                sigmas=np.sqrt(np.diag(q)))
            sol_index.extend((image, n) for n in names)
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
        sh = engine.shifts
        if sh is not None:
            k0 = sh.first
            q_shift = _cofactor_block(st.q_pp, np.arange(k0, s.n_params)) * var0
            for i_src, source in enumerate(sh.sources):
                idx = sh.index[i_src]
                have = idx >= 0
                values = np.zeros(3)
                cov3 = np.zeros((3, 3))
                values[have] = out.x[idx[have]]
                cov3[np.ix_(have, have)] = q_shift[np.ix_(idx[have] - k0, idx[have] - k0)]
                where = ("block" if len(solutions) == 1 else f"group {len(solution_cov) + 1}"
                         ) if mode == "block" else s.ids[0]
                key = source if where == "block" else f"{source} @ {where}"
                shifts[key] = SourceShift(
                    source=source, solution=where,
                    values=values, sigmas=np.sqrt(np.diag(cov3)),
                    prior_sigmas=sh.prior_sigma[i_src].copy(), covariance=cov3,
                    lon=float(sh.centroid[i_src, 0]), lat=float(sh.centroid[i_src, 1]),
                    h=float(sh.centroid[i_src, 2]), n_points=int(sh.n_points[i_src]))
        k_models = s.n_model_params  # the source shifts come after
        if isinstance(st.q_pp, SelectedCofactor):  # the selected images' columns only
            held = st.q_pp.columns[st.q_pp.columns < k_models]
            solution_cov.append(st.q_pp.block(held) * var0)
            index.extend(sol_index[c] for c in held)
            if not engine.full_covariance():
                notes.append(_covariance_note(engine, held.size))
        else:
            solution_cov.append(st.q_pp[:k_models, :k_models] * var0)
            index.extend(sol_index)
        if s.hcp_h is not None:
            j = np.flatnonzero(np.isfinite(s.hcp_h))
            hcp_parts.append((s.p_id[j], s.hcp_h[j], ev.h[j], s.hcp_sigma[j]
                              if s.hcp_sigma is not None else np.full(j.size, np.nan),
                              np.sqrt(cov_enu[j, 2, 2])))
    if len(solution_cov) == 1:  # one solution: the full covariance, cross-image terms
        covariance = solution_cov[0]
    else:  # independent solutions (images, or groups): block diagonal
        k = sum(b.shape[0] for b in solution_cov)
        covariance = np.zeros((k, k))
        o = 0
        for b in solution_cov:
            covariance[o:o + b.shape[0], o:o + b.shape[0]] = b
            o += b.shape[0]
    sigma0 = math.sqrt(cost / dof) if dof > 0 else float("nan")
    statements = list(dict.fromkeys(out.system.solver_statement for _, out, _ in solutions
                                    if out.system.solver_statement))
    solver = ("; ".join(statements) if len(statements) <= 3 else
              "; ".join(statements[:3]) + f"; and {len(statements) - 3} other statement(s)")

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
        good = np.flatnonzero(np.isfinite(weight) & (weight > 0) & ~flagged)
        # grouped by image once: no scan of every measurement per image
        image_ids = list(models)
        of_image = lookup(np.array(image_ids), meas.image[good])
        order = np.argsort(of_image, kind="stable")
        start = np.searchsorted(of_image[order], np.arange(len(image_ids) + 1))
        for k, image in enumerate(image_ids):
            use = good[order[start[k]: start[k + 1]]]
            if use.size < 3:
                notes.append(f"collocation: image {image} has {use.size} residual "
                             "vectors, fewer than 3: not applied")
                continue
            col = fit_collocation(meas.row[use], meas.col[use], v[use, 0], v[use, 1], **options)
            models[image] = CollocationCorrection(models[image], col)

    check, predicted, v_check, pred_cov = _check_points(block, models, q_by_image, sigma0,
                                                        adjusted)
    ground = block.ground
    check_source = (np.empty(0, str) if ground is None or not len(check)
                    else ground.source[lookup(ground.id, check.id)])
    vertical = None
    full = all(engine.full_covariance() for engine, _, _ in solutions)
    if ground is not None and np.any(meas.kind == "icp") and not full:
        notes.append("vertical check at the ICPs not computed: it needs the full covariance")
    elif ground is not None and np.any(meas.kind == "icp"):
        from geoblock.adjust._vertical import vertical_check

        vertical = vertical_check(block, models, adjusted, covariance, index)
    from geoblock.adjust._vertical import grid_covariances

    grid = grid_covariances(block, adjusted, {
        image: (parameters[image].names, q_by_image[image][1]) for image in q_by_image})
    hcp = None
    if hcp_parts:
        ids_h, obs_h, adj_h, sig_h, post_h = (np.concatenate(x) for x in zip(*hcp_parts,
                                                                              strict=True))
        _, first_h = np.unique(ids_h, return_index=True)
        first_h = np.sort(first_h)
        assert ground is not None  # HCPs come from the ground points
        hcp = HeightControlResults(
            id=ids_h[first_h].astype(str), source=ground.source[lookup(ground.id,
                                                                      ids_h[first_h])],
            observed=obs_h[first_h], adjusted=adj_h[first_h], sigma=sig_h[first_h],
            posterior_sigma=post_h[first_h])
    if ground is not None:
        unused = ~np.isin(ground.id, meas.id) & (ground.kind != "icp")
        if unused.any():
            notes.append(f"{int(unused.sum())} ground control point(s) with no image "
                         f"measurement left out: {', '.join(ground.id[unused][:8].tolist())}"
                         f"{' ...' if unused.sum() > 8 else ''}")
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
        robust=robust, notes=notes, predicted_covariance=pred_cov, check_source=check_source,
        shifts=shifts, hcp=hcp, vertical=vertical, grid_covariance=grid, solver=solver)


def _cofactor_block(q_pp: Any, cols: IndexArray) -> Float64Array:
    """``Q_pp[cols][:, cols]`` of a dense cofactor or a SelectedCofactor (NaN not held)."""
    if isinstance(q_pp, SelectedCofactor):
        if q_pp.columns.size == 0:  # nothing held (SelectedCofactor.block indexes its q)
            return np.where(np.asarray(cols)[:, None] < 0, 0.0,
                            np.full((len(cols), len(cols)), np.nan))
        return q_pp.block(cols)
    return np.asarray(q_pp[np.ix_(cols, cols)], dtype=np.float64)


def _covariance_note(engine: _Engine, held: int) -> str:
    k = engine.s.n_params
    what = ("none" if isinstance(engine.covariance, str)
            else f"those of {len(engine.covariance)} requested image(s), {held} columns")
    return (f"covariances: {k} parameters; the parameter cofactors computed are {what} "
            f"(covariance={engine.covariance!r}; 'auto' computes the full one up to "
            f"{DENSE_LIMIT} parameters): the other parameters' sigmas, the point covariances "
            "and the redundancy numbers and test statistics that need them are NaN")


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
                  ) -> tuple[PointErrors, Float64Array, Float64Array, Float64Array]:
    """GCP/ICP ground errors per measurement through ``models``, their sigmas predicted
    through ``adjusted`` (the models whose parameters ``q_by_image`` gives, per image, the
    adjusted indices and their covariance of; default ``models``), image residuals, and the
    predicted east/north covariances (N, 2, 2). A point's own survey sigmas and its source's
    common error (``sigma_shift_*``) count as independent errors of the reference."""
    adjusted = models if adjusted is None else adjusted
    meas = block.measurements
    n = len(meas)
    v = np.full((n, 2), np.nan)
    ground = block.ground
    sel = np.flatnonzero(np.isin(meas.kind, ("gcp", "icp")))
    if ground is None or sel.size == 0:
        empty = np.empty(0)
        return PointErrors(np.empty(0, str), np.empty(0, str), empty, empty), \
            np.empty((0, 2)), v, np.empty((0, 2, 2))
    g = lookup(ground.id, meas.id[sel])
    lon, lat, h = ground.lon[g], ground.lat[g], ground.h[g]
    e = np.full(sel.size, np.nan)
    nn = np.full(sel.size, np.nan)
    pred = np.full((sel.size, 2), np.nan)
    pred_cov = np.full((sel.size, 2, 2), np.nan)
    ref_e2 = ground.sigma_e[g] ** 2 + ground.sigma_shift_e[g] ** 2
    ref_n2 = ground.sigma_n[g] ** 2 + ground.sigma_shift_n[g] ** 2
    ref_h2 = ground.sigma_h[g] ** 2 + ground.sigma_shift_h[g] ** 2
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
        cov_img = cov_img + up @ np.swapaxes(up, 1, 2) * ref_h2[mine][:, None, None]
        cov = m_inv @ cov_img @ np.swapaxes(m_inv, 1, 2)
        cov[:, 0, 0] += ref_e2[mine]
        cov[:, 1, 1] += ref_n2[mine]
        pred[mine] = np.sqrt(np.einsum("nii->ni", cov))
        pred_cov[mine] = cov
    check = PointErrors(meas.id[sel], meas.kind[sel], e, nn, None, v[sel, 0], v[sel, 1],
                        meas.image[sel])
    return check, pred, v, pred_cov
