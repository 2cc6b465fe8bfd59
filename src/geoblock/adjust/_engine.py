"""The Gauss-Newton / Levenberg-Marquardt engine of :func:`geoblock.adjust.block.adjust`: one
solution of a block (or of one image), its set-up checks, linearisation, robust re-weighting
and statistics. Private: :mod:`geoblock.adjust.block` is the public entry point."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse
import scipy.stats

from geoblock import coords
from geoblock.adjust._control import (
    padded_columns,
    pseudo_measurements,
    source_shifts,
)
from geoblock.adjust.normal import (
    DENSE_LIMIT,
    NormalSystem,
    SelectedCofactor,
    SingularPoints,
    compress_columns,
    measurement_pairs,
)
from geoblock.adjust._start import WarmStart
from geoblock.adjust.observations import ImagePoints, lookup
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

from geoblock.adjust.problem import (
    COST_TOLERANCE,
    CREEP_COST_TOLERANCE,
    FLOATING_TP_SIGMA_M,
    ITERATE_HOLD_SIGMA_M,
    MIN_GROUND_SIGMA_M,
    Block,
)
from geoblock.adjust.weights import parameter_prior


# ================================================================================ engine
#: the points per image at which an adjusted model is checked not degenerate
#: (:func:`~geoblock.adjust.weights.check_not_degenerate`: a median over them)
DEGENERATE_SAMPLE = 64


@dataclass
class _Setup:
    """Everything fixed during a solution."""

    ids: tuple[str, ...]
    models: list[SensorModel]
    adj: list[IndexArray]  # per image, the indices of its adjustable parameters
    gidx: IndexArray  # (images, max adjustable): position of each in the parameter vector
    n_params: int
    prior_x: Float64Array  # (K,) a-priori values of the adjustable parameters
    prior_w: Any  # (K, K) prior weight, scipy.sparse CSR (block diagonal)
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
    n_model_params: int = -1  # K of the models (n_params less the source shifts)
    hcp_h: Float64Array | None = None  # (J,) observed height of the HCPs, NaN elsewhere
    hcp_sigma: Float64Array | None = None  # (J,) their sigma_h, metres
    by_image: IndexArray | None = None  # (M,) the measurements grouped by image (stable)
    image_start: IndexArray | None = None  # (I + 1,) where each image's run begins in it

    def of_image(self, i: int) -> IndexArray:
        """The measurements of image ``i`` (ascending): O(1), no scan of ``image_of``."""
        assert self.by_image is not None and self.image_start is not None
        return self.by_image[self.image_start[i]: self.image_start[i + 1]]


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
    cost_fixed: float  # parameter, DEM and HCP terms
    offset: Float64Array | None = None  # (J, 3) the sources' shifts at each point, local
    cost: float = math.nan


@dataclass
class _Statistics:
    """Cofactors, redundancy numbers and test statistics of a solution."""

    q_pp: Any  # (K, K) ndarray, or a SelectedCofactor (NaN where not held)
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
                 tp_prior: str, notes: list[str], solver: str = "auto",
                 covariance: str | tuple[str, ...] = "auto",
                 start: WarmStart | None = None) -> None:
        self.block = block
        self.solver = solver
        self.covariance = covariance
        self.tp_prior = tp_prior
        self.tp_sigma_m_first = FLOATING_TP_SIGMA_M
        self.dem_control = dem_control if block.dem is not None else "none"
        self.notes = notes
        meas = block.measurements
        models = [block.models[i] for i in ids]
        priors = [parameter_prior(m, block.sigmas.get(i, {}))
                  for i, m in zip(ids, models, strict=True)]
        adj = [np.flatnonzero(mask) for mask, _ in priors]
        self.priors = priors
        sizes = np.array([a.size for a in adj])
        kmax = max(int(sizes.max()), 1)
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        gidx = np.full((len(ids), kmax), -1, np.intp)
        for i, (o, s) in enumerate(zip(offsets, sizes, strict=True)):
            gidx[i, :s] = o + np.arange(s)
        k = int(sizes.sum())
        # block diagonal, one block per image: sparse (a dense (K, K) array would be 28.8 GB
        # at 10^4 images of 6 parameters)
        prior_w = scipy.sparse.block_diag(
            [prior_weight(priors[i][1][np.ix_(adj[i], adj[i])]) for i in range(len(models))
             if sizes[i]] or [np.zeros((0, 0))], format="csr", dtype=np.float64)
        prior_w = scipy.sparse.csr_matrix(prior_w, shape=(k, k))
        prior_x = _params_vector(models, adj, gidx, k)

        # the starting estimate: the a-priori values, or a previous solution's
        self.x_start = prior_x.copy()
        trusted = np.zeros(len(ids), bool)  # images starting from a previous solution
        if start is not None:
            for i, image in enumerate(ids):
                values = start.parameters.get(image)
                if not values:
                    continue
                trusted[i] = True
                names = models[i].parameters.names
                for kk, a in enumerate(adj[i]):
                    if names[a] in values:
                        self.x_start[gidx[i, kk]] = values[names[a]]
        kinds = ("gcp", "tp", "hcp") if use_tps else ("gcp",)
        sel = np.flatnonzero(np.isin(meas.image, ids) & np.isin(meas.kind, kinds))
        # points in the solution
        p_id, point_of = np.unique(meas.id[sel], return_inverse=True)
        image_of = lookup(np.array(ids), meas.image[sel])
        # grouped by image once (CSR): the per-image slices of the hot path cost O(1)
        by_image = np.argsort(image_of, kind="stable").astype(np.intp)
        image_start = np.searchsorted(image_of[by_image], np.arange(len(ids) + 1)).astype(
            np.intp)
        self._by_image, self._image_start, self._image_of = by_image, image_start, image_of
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
        is_tp = ~is_gcp  # tie points and height control points (tie points with a height)
        is_hcp = p_kind == "hcp"
        hcp_h = hcp_sigma = None
        if is_hcp.any():
            assert ground is not None  # HCP kinds come from the ground points
            hcp_h = np.where(is_hcp, ground.h[gk], np.nan)
            hcp_sigma = np.where(is_hcp, ground.sigma_h[gk], np.nan)
        # warm start: the points a previous solution holds start where it left them
        w_at = (lookup(start.id, p_id) if start is not None and start.id.size
                else np.full(p_id.size, -1))
        warm = w_at >= 0
        if is_tp.any():
            # floating TP priors are centred on the starting positions: the warm TPs need no
            # ray tracing; fixed ones are centred on the on-board positions: all traced
            cold = is_tp & ~warm if tp_prior == "floating" else is_tp
            at = None if hcp_h is None else hcp_h[cold]
            if cold.any():
                # a warm start traces the new points through the solved images' models
                # (only theirs where they see the point), the others' on-board ones
                lon0[cold], lat0[cold], h0[cold] = self._initial_tps(
                    models if start is None else _with_params(models, adj, gidx,
                                                              self.x_start),
                    ids, meas, sel, point_of, np.flatnonzero(cold), at,
                    trusted=None if start is None or tp_prior != "floating" else trusted)
            if tp_prior == "floating" and start is not None:
                hot = is_tp & warm
                lon0[hot], lat0[hot], h0[hot] = (start.lon[w_at[hot]], start.lat[w_at[hot]],
                                                 start.h[w_at[hot]])
            if hcp_h is not None:  # an HCP's lon/lat, when given, as its initial position
                assert ground is not None
                given = is_hcp & np.isfinite(ground.lon[gk]) & np.isfinite(ground.lat[gk])
                lon0[given], lat0[given] = ground.lon[gk[given]], ground.lat[gk[given]]
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
        # DEM control holds the tie points, not the HCPs: their height is observed better
        dem_rows = (p_kind == "tp") & (self.dem_control != "none")
        self.shifts = source_shifts(ground, p_id, p_kind, lon0, lat0, h0, frame, k)
        if self.shifts is not None:
            k_all = k + self.shifts.count
            sig_shift = self.shifts.prior_sigma[self.shifts.index >= 0]
            w_all = scipy.sparse.block_diag(
                [prior_w, scipy.sparse.diags(1.0 / np.maximum(sig_shift, MIN_GROUND_SIGMA_M)
                                             ** 2)], format="csr")
            prior_w, prior_x = w_all, np.concatenate([prior_x, np.zeros(k_all - k)])
            self.x_start = np.concatenate([self.x_start, np.zeros(k_all - k)])
        self.s = _Setup(
            ids=ids, models=models, adj=adj, gidx=gidx, n_params=k, prior_x=prior_x,
            prior_w=prior_w, m_sel=sel, image_of=image_of, point_of=point_of,
            obs=np.stack([meas.row[sel], meas.col[sel]], -1),
            sigma=np.stack([meas.sigma_row[sel], meas.sigma_col[sel]], -1),
            p_id=p_id, p_kind=p_kind, frame=frame, x0=x0, g_center=x0.copy(),
            g_weight=g_weight, dem_rows=dem_rows, n_images=n_images, n_model_params=k,
            hcp_h=hcp_h, hcp_sigma=hcp_sigma, by_image=by_image, image_start=image_start,
        )
        if self.shifts is not None:
            self.s.n_params = prior_x.size
            # the shifted points' ground rows are pseudo-measurements of (point, shift)
            self.g_chol_t = np.swapaxes(np.linalg.cholesky(g_weight), 1, 2)
            self.pseudo_point = np.repeat(np.flatnonzero(self.shifts.shifted), 2)
            point_of = np.concatenate([point_of, self.pseudo_point])
        self.pairs = measurement_pairs(point_of, p_id.size)
        self.pts_start = x0.copy()
        if start is not None:
            if warm.any():
                self.pts_start[warm] = np.stack(frame.from_geodetic(
                    start.lon[w_at[warm]], start.lat[w_at[warm]], start.h[w_at[warm]]), -1)
            notes.append(f"warm start from {start.source}: "
                         f"{sum(1 for i in ids if start.parameters.get(i))} of {len(ids)} "
                         f"images and {int(warm.sum())} of {p_id.size} points start from it")
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
            mine = sel[self._by_image[self._image_start[i]: self._image_start[i + 1]]]
            check_measured_geometry(
                meas.id[mine], meas.row[mine], meas.col[mine],
                [f"{image}:{models[i].parameters.names[a]}" for a in adj[i][free]],
                f"block: image {image!r}")

    def _initial_tps(self, models: list[SensorModel], ids: tuple[str, ...], meas: ImagePoints,
                     sel: IndexArray, point_of: IndexArray, tp_points: IndexArray,
                     heights: Float64Array | None = None, trusted: BoolArray | None = None,
                     ) -> tuple[Float64Array, Float64Array, Float64Array]:
        """Initial TP positions: each ray localised on the DEM (or at the GCPs' mean
        height), averaged in ECEF; then put on the DEM. Points with a finite ``heights``
        (per ``tp_points``: the HCPs) are located at that height instead. With ``trusted`` (I,)
        (a warm start's solved images), a point seen by a trusted image is averaged from the
        trusted images' rays only."""
        from geoblock.dem.intersect import localize

        block = self.block
        want = np.isin(point_of, tp_points)
        m_idx = sel[want]
        xyz = np.full((m_idx.size, 3), np.nan)
        img = self._image_of[want]
        order = np.argsort(img, kind="stable")
        start = np.searchsorted(img[order], np.arange(len(ids) + 1))
        row_w, col_w = meas.row[m_idx], meas.col[m_idx]
        for i, image in enumerate(ids):
            mine = order[start[i]: start[i + 1]]  # grouped once: no scan per image
            if not mine.size:
                continue
            rows, cols = row_w[mine], col_w[mine]
            if block.dem is not None:
                g, _ = localize(models[i], rows, cols, block.dem, warn=False)
            else:
                h_guess = (float(np.nanmean(block.ground.h))
                           if block.ground is not None and len(block.ground)
                           else float(np.mean(models[i].height_range)))
                g, _ = models[i].backproject_with_status(rows, cols,
                                                         np.full(rows.shape, h_guess))
            xyz[mine] = np.stack(coords.geodetic_to_ecef(*g), axis=-1)
        if heights is not None:
            at = np.full(point_of.max() + 1, np.nan)
            at[tp_points] = heights
            h_ray = at[point_of[want]]
            for i, image in enumerate(ids):
                mine = order[start[i]: start[i + 1]]
                mine = mine[np.isfinite(h_ray[mine])]
                if mine.size:
                    g, _ = models[i].backproject_with_status(row_w[mine], col_w[mine],
                                                             h_ray[mine])
                    xyz[mine] = np.stack(coords.geodetic_to_ecef(*g), axis=-1)
        pts = point_of[want]
        sums = np.zeros((point_of.max() + 1, 3))
        cnt = np.zeros(point_of.max() + 1)
        ok = np.all(np.isfinite(xyz), axis=1)
        if trusted is not None:  # a point seen by a trusted image: its rays only
            mine = ok & trusted[img]
            seen = np.bincount(pts[mine], minlength=point_of.max() + 1) > 0
            ok &= ~seen[pts] | trusted[img]
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
        if heights is not None:
            h = np.where(np.isfinite(heights), heights, h)
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
            mine = s.of_image(i)
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
        offset = None if self.shifts is None else self.shifts.offsets(x)
        dem = self._dem_rows(lon, lat, h, pts)
        if s.hcp_h is not None:
            self._hcp_rows(dem, lon, lat, h, offset)
        ev = _Evaluation(models=models, v=v, vw=vw, status=status, ok=ok, lon=lon, lat=lat, h=h,
                         dem=dem, pts=pts, cost_fixed=float(dp @ (s.prior_w @ dp))
                         + float(np.nansum((dem.misclosure / dem.sigma) ** 2)), offset=offset)
        self.recost(ev)
        return ev

    def recost(self, ev: _Evaluation) -> None:
        """``ev.cost`` again after the robust weights or the ground pseudo-observations
        changed (no projection)."""
        s = self.s
        dg = ev.pts - s.g_center
        if ev.offset is not None:  # GCPs: observed = point + their source's shift
            dg = dg + np.where((s.p_kind == "gcp")[:, None], ev.offset, 0.0)
        ev.cost = (float(np.sum(self.weight[:, None] * ev.vw ** 2)) + ev.cost_fixed
                   + float(np.einsum("ji,jik,jk->", dg, s.g_weight, dg)))

    def _hcp_rows(self, dem: _DemRows, lon: Float64Array, lat: Float64Array,
                  h: Float64Array, offset: Float64Array | None) -> None:
        """The HCPs' height observations ``h_obs - h(x) [- the source's shift up]`` into the
        rows of ``dem`` (in place; an HCP has no DEM row)."""
        s = self.s
        assert s.hcp_h is not None and s.hcp_sigma is not None
        rows = np.flatnonzero(np.isfinite(s.hcp_h))
        up = _local_to_enu_rotation(s.frame, lon[rows], lat[rows])[:, 2, :]  # d h / d local
        dem.grad[rows] = up
        mis = s.hcp_h[rows] - h[rows]
        if offset is not None:
            mis = mis - np.einsum("ji,ji->j", up, offset[rows])
        dem.misclosure[rows] = mis
        dem.sigma[rows] = s.hcp_sigma[rows]

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
        b = np.zeros((m_count, 2, 3))
        rot_t = s.frame.rotation.T  # d ECEF / d local
        # each measurement's parameter partials in the columns it touches (compress_columns):
        # a model whose parameters act locally (splines in time) fills a few of its image's
        parts = []
        for i, model in enumerate(ev.models):
            mine = s.of_image(i)
            if mine.size == 0:
                continue
            j = s.point_of[mine]
            lon, lat, h = ev.lon[j], ev.lat[j], ev.h[j]
            if s.adj[i].size:
                # both partials at once where the model offers it (SensorModelBase.partials:
                # a pushbroom solves its points once for the two), the protocol's two else
                both = getattr(model, "partials", None)
                if callable(both):
                    ground, partials = both(lon, lat, h)
                else:
                    ground = model.partials_ground(lon, lat, h)
                    partials = model.partials_parameters(lon, lat, h)
                if s.adj[i].size < partials.shape[-1]:  # (all adjusted: no copy)
                    partials = partials[..., s.adj[i]]
                failed = ~ev.ok[mine]
                if failed.any():  # zero, as the whitening below makes them
                    partials = np.where(failed[:, None, None], 0.0, partials)
                parts.append((mine, *compress_columns(partials, s.gidx[i, : s.adj[i].size])))
            else:
                ground = model.partials_ground(lon, lat, h)
            b[mine] = ground @ rot_t
        kc = max((c.shape[1] for _, _, c in parts), default=0)
        a = np.zeros((m_count, 2, kc))
        cols = np.full((m_count, kc), -1, np.intp)
        for mine, a_i, c_i in parts:
            a[mine, :, : c_i.shape[1]] = a_i
            cols[mine, : c_i.shape[1]] = c_i
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
        g_weight = s.g_weight
        cols_all: IndexArray = cols
        point_of, image_of = s.point_of, s.image_of
        if self.shifts is not None:  # the shifted points' ground rows as pseudo-measurements
            a, b, vw, cols_all, point_of, image_of = self._with_pseudo(
                ev, a, b, vw, cols, has, dw)
            shifted = self.shifts.shifted
            g_weight = np.where((shifted & (s.p_kind == "gcp"))[:, None, None], 0.0, g_weight)
            dw = np.where(shifted & (s.p_kind == "hcp"), 0.0, dw)
        n_extra = g_weight + dw[:, None, None] * dem.grad[:, :, None] * dem.grad[:, None]
        b_extra = (np.einsum("jik,jk->ji", g_weight, s.g_center - pts)
                   + (dw * np.where(has, dem.misclosure, 0.0))[:, None] * dem.grad)
        return NormalSystem(
            n_params=s.n_params, gidx=s.gidx, image_of=image_of, point_of=point_of,
            a=a, b=b, v=vw, n_pp_prior=s.prior_w, b_p_prior=np.asarray(s.prior_w @ (s.prior_x - x)),
            n_xx_extra=n_extra, b_x_extra=b_extra, pairs=self.pairs, cols=cols_all,
            solver=self.solver,
        )

    def _with_pseudo(self, ev: _Evaluation, a: Float64Array, b: Float64Array,
                     vw: Float64Array, cols: IndexArray, has: BoolArray, dw: Float64Array,
                     ) -> tuple[Float64Array, Float64Array, Float64Array, IndexArray,
                                IndexArray, IndexArray]:
        """The image measurements' whitened rows (robust weights applied) with the shifted
        points' ground rows appended as pseudo-measurements; the statistics' a-priori
        whitened rows (:attr:`prior_whitened`) likewise."""
        s = self.s
        shifts = self.shifts
        assert shifts is not None and ev.offset is not None
        dem = ev.dem
        g_res = s.g_center - ev.pts - np.where((s.p_kind == "gcp")[:, None], ev.offset, 0.0)
        sigma = np.where(has, np.sqrt(1.0 / np.where(dw > 0, dw, 1.0)), np.inf)
        point, pa, pb, pcols, pv = pseudo_measurements(
            shifts, s.p_kind == "gcp", self.g_chol_t, g_res, dem.grad,
            np.where(has, dem.misclosure, np.nan), sigma)
        (a_all, cols_all), (pa0, _) = padded_columns(a, cols, pa, pcols), self.prior_whitened
        self.prior_whitened = (padded_columns(pa0, cols, pa, pcols)[0],
                               np.concatenate([self.prior_whitened[1], pb]))
        return (a_all, np.concatenate([b, pb]), np.concatenate([vw, pv]), cols_all,
                np.concatenate([s.point_of, point]),
                np.concatenate([s.image_of, np.zeros(point.size, np.intp)]))

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
            if reduced.shape[0] > DENSE_LIMIT:  # no (K, K) dense array for the diagnosis
                return SingularSystemError(
                    f"block: singular normal equations ({exc}); with {reduced.shape[0]} "
                    "parameters the undetermined ones are not searched for: adjust a part of "
                    "the block, or give the parameters a-priori sigmas", ())
            reduced = reduced.toarray()
        labels = [""] * s.n_params
        if self.shifts is not None:
            labels[self.shifts.first:] = self.shifts.labels()
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
        if robust == "snooping" and not self.full_covariance():
            raise AdjustmentError(
                f"{label}: robust='snooping' tests every measurement with its redundancy, "
                f"which needs the full parameter cofactor: {s.n_params} parameters here, "
                f"covariance={self.covariance!r} (the full one is computed up to "
                f"{DENSE_LIMIT} with 'auto'); use robust='huber' or 'cauchy', or "
                "covariance='full'")
        x = self.x_start.copy()
        pts = self.pts_start.copy()
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
            # the step's length in the undamped system's metric, delta^T N delta (= delta^T b
            # less the damping's share): no unknown moved by more than its square root times
            # its posterior cofactor sigma (Cauchy-Schwarz), whatever the correlations. The
            # 1 / sqrt(diag) sigmas of `step` are lower bounds, far too small for strongly
            # correlated unknowns: a TP on nearly parallel rays held by the floating prior
            # alone, a spline knot and the TPs of its time. There the damped steps creep by
            # 1e-3 of them per iteration, reducing the cost by 1e-8 of itself, long after
            # the parameters have settled (2e-6 posterior sigmas from where 39 iterations
            # end, on knots every 40 lines in tests/adjust/test_jitter_block.py's block)
            decrement = float(dp @ system.b_p + np.sum(dx * system.b_x))
            if lam:
                decrement -= lam * float(system.n_pp_diagonal @ dp ** 2 + np.sum(
                    np.einsum("jii->ji", system.n_xx) * dx ** 2))
            x, pts, ev = x_new, pts_new, ev_new
            if self.tp_prior == "floating":
                # re-centred on the estimate, and released after the first step: a damping
                # of the first step from the on-board positions, never a pull on the solution
                tp = s.p_kind != "gcp"  # tie points and HCPs
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
            small = (step < tolerance or abs(rel) < COST_TOLERANCE
                     or (self.dem_control != "iterate" and decrement < tolerance ** 2
                         and abs(rel) < CREEP_COST_TOLERANCE))
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
            mine = s.of_image(i)
            if mine.size and s.adj[i].size:
                # the median area scale of at most DEGENERATE_SAMPLE points spread over the
                # image's measurements (every 1 in n): the same test at any block size, not
                # two more Jacobians of every measurement
                j = s.point_of[mine][:: max(1, -(-mine.size // DEGENERATE_SAMPLE))]
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
        prior = int(np.sum(s.prior_w.diagonal() > 0))
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

    def full_covariance(self) -> bool:
        """Whether :meth:`statistics` computes the full parameter cofactor."""
        return self.covariance == "full" or (self.covariance == "auto"
                                            and self.s.n_params <= DENSE_LIMIT)

    def statistics(self, ev: _Evaluation, system: NormalSystem) -> _Statistics:
        """Per-measurement hat blocks, redundancy and leave-one-out test statistics.

        ``covariance`` (the engine's): the full ``Q_pp`` (``"full"``, or ``"auto"`` up to
        :data:`DENSE_LIMIT` parameters), the columns of some images (a sequence of image
        ids: :meth:`NormalSystem.cofactor_columns`, solved from the factorisation), or none
        (``"none"``, ``"auto"`` above): what is not held is NaN downstream."""
        s = self.s
        q_pp: Any
        if self.full_covariance():
            q_pp = system.parameter_cofactor()
        elif isinstance(self.covariance, str):  # none
            q_pp = SelectedCofactor(n_params=s.n_params, columns=np.zeros(0, np.intp),
                                    q=np.zeros((0, 0)))
        else:
            mine = np.flatnonzero(np.isin(np.array(s.ids), list(self.covariance)))
            q_pp = system.parameter_cofactor(system.cofactor_columns(images=mine))
        q_xx, q_px = system.point_cofactors(q_pp)
        w = np.where(ev.ok, self.weight, 0.0)
        # D = J Q J^T / sigma^2 (a-priori whitening), every measurement, rejected ones too
        d = system.hat_blocks(q_pp, q_xx, q_px, *self.prior_whitened)[: s.obs.shape[0]]
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
