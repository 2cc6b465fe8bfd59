"""Multi-ray triangulation for any sensor models: :func:`triangulate`.

A point measured in ``n >= 2`` images is placed where its lines of sight come closest: the
least-squares point of the rays in ECEF (the sum of its squared perpendicular distances to
the rays is smallest). Only the :class:`~geoblock.models.SensorModel` protocol is used:

1. *Rays.* Each measurement is backprojected at two heights (``backproject_with_status``);
   the ECEF line through the two points is its ray. The first pass takes the ends of the
   model's ``height_range``.
2. *Intersection.* Per point, ``sum_i (I - d_i d_i^T) X = sum_i (I - d_i d_i^T) p_i`` (3 x 3,
   solved for all points at once).
3. *Refinement.* The rays of a pushbroom or an RPC are not exactly straight over the whole
   height range: each ray is taken again between ``h - step`` and ``h + step`` around the
   point's current height ``h``, and step 2 repeated, until the point moves by at most
   ``tolerance_m`` (per point: ``CONVERGED``, or ``MAX_ITERATIONS`` at the cap).
4. *Quality.* Per ray: the point's perpendicular distance to it (metres), its foot on the
   ray, and the residual ``measured - project(point)`` (pixels). Per point: the *miss
   distance* (twice the RMS of its distances to its rays: for two rays, the shortest
   distance between them, ASP's triangulation error) and the first-order covariance of the
   point from the image sigmas and, when given, the models' parameter covariances (through
   ``partials_ground`` and ``partials_parameters``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock import coords
from geoblock._array import warn_status
from geoblock.errors import ObservationError, ShapeMismatchError
from geoblock.typing import ArrayLike, Float64Array, Status

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel

__all__ = ["Triangulation", "parameter_covariances", "triangulate", "warn_triangulation"]

_OK = np.uint8(Status.CONVERGED)
_MAX_ITERATIONS = np.uint8(Status.MAX_ITERATIONS)
_NO_INTERSECTION = np.uint8(Status.NO_INTERSECTION)
_INVALID = np.uint8(Status.INVALID_INPUT)

#: smallest eigenvalue of sum(I - d d^T) below which the rays are taken as parallel
#: (for two rays it is about 1 - cos(angle): 1e-10 is an angle of 3 arc seconds)
_PARALLEL = 1e-10


@dataclass(frozen=True, eq=False)
class Triangulation:
    """Points triangulated from their image measurements.

    Per point, arrays ``(N,)`` in the order the points are first met in the measurements;
    per measurement, arrays ``(K,)`` in the measurements' order.

    Attributes
    ----------
    id : ndarray of str, (N,)
    lon, lat, h : ndarray, (N,)
        Degrees, metres above the WGS84 ellipsoid; NaN unless ``status`` is ``CONVERGED``.
    miss_m : ndarray, (N,)
        Twice the RMS distance of the point to its rays, metres (two rays: their shortest
        distance).
    rays : ndarray of int, (N,)
        The point's rays: its measurements whose model could backproject them.
    covariance : ndarray, (N, 3, 3)
        Covariance of the point along local east, north, up, square metres (first order, from
        the image sigmas and the parameter covariances given); NaN where not computed.
    status : ndarray of uint8, (N,)
        :class:`~geoblock.typing.Status`: ``CONVERGED``; ``MAX_ITERATIONS``;
        ``NO_INTERSECTION`` (fewer than two usable rays, or parallel rays); the model's own
        status when a model could not backproject the rays the point needed.
    point : ndarray of int, (K,)
        Index of each measurement's point.
    v_row, v_col : ndarray, (K,)
        Measured minus computed (the point projected into the image), pixels.
    distance_m : ndarray, (K,)
        Perpendicular distance of the point to the measurement's ray, metres.
    foot : ndarray, (K, 3)
        The ray's point nearest to the triangulated point, ECEF metres (for two rays, the
        ends of their common perpendicular).
    ray_status : ndarray of uint8, (K,)
        The model's status for each ray (``CONVERGED`` when it could be backprojected).
    """

    id: np.ndarray
    lon: Float64Array
    lat: Float64Array
    h: Float64Array
    miss_m: Float64Array
    rays: np.ndarray
    covariance: Float64Array
    status: np.ndarray
    point: np.ndarray
    v_row: Float64Array
    v_col: Float64Array
    distance_m: Float64Array
    foot: Float64Array
    ray_status: np.ndarray

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @property
    def sigma_enu(self) -> Float64Array:
        """(N, 3) standard deviations along east, north, up, metres."""
        return np.sqrt(np.einsum("nii->ni", self.covariance))

    @property
    def residual_rms_px(self) -> Float64Array:
        """(N,) RMS of the point's residuals over its rays and both axes, pixels."""
        sq = np.where(np.isfinite(self.v_row), self.v_row**2 + self.v_col**2, 0.0)
        n = np.bincount(self.point, weights=np.isfinite(self.v_row), minlength=len(self))
        with np.errstate(invalid="ignore", divide="ignore"):
            rms = np.sqrt(np.bincount(self.point, weights=sq, minlength=len(self)) / (2 * n))
        return np.where(n > 0, rms, np.nan)

    def to_columns(self, image: ArrayLike) -> dict[str, np.ndarray]:
        """The per-point table ``geoblock triangulate`` writes.

        ``id, lon, lat, h, miss_m, rays, rms_px, sigma_e, sigma_n, sigma_h``, then per
        image the residuals ``v_row_<image>, v_col_<image>`` (NaN where the image did not
        measure the point), then ``status``.

        Parameters
        ----------
        image : array_like of str, (K,)
            The image of each measurement (as given to :func:`triangulate`).
        """
        images = np.asarray(image).astype(str)
        sig = self.sigma_enu
        out: dict[str, np.ndarray] = {
            "id": self.id, "lon": self.lon, "lat": self.lat, "h": self.h,
            "miss_m": self.miss_m, "rays": self.rays, "rms_px": self.residual_rms_px,
            "sigma_e": sig[:, 0], "sigma_n": sig[:, 1], "sigma_h": sig[:, 2],
        }
        for name in dict.fromkeys(images.tolist()):
            sel = images == name
            for axis, v in (("row", self.v_row), ("col", self.v_col)):
                col = np.full(len(self), np.nan)
                col[self.point[sel]] = v[sel]
                out[f"v_{axis}_{name}"] = col
        names = np.array([Status(v).name.lower() for v in range(len(Status))])
        out["status"] = names[np.minimum(self.status, len(Status) - 1)]
        return out


def parameter_covariances(result: Any) -> dict[str, Float64Array]:
    """The posterior parameter covariance of each image of a block adjustment, for
    :func:`triangulate`'s ``parameter_covariance``.

    Parameters
    ----------
    result : geoblock.adjust.BlockResult
        Its ``covariance`` (K, K), ``parameter_index`` ((image, name) of each row) and
        ``models``.

    Returns
    -------
    dict of str to ndarray, (P, P)
        Per image, over all of its model's ``P`` parameters in their order (zero for the
        parameters the adjustment held fixed). Cross-image terms are not kept.
    """
    cov = np.asarray(result.covariance, dtype=np.float64)
    index = {(str(i), str(n)): k for k, (i, n) in enumerate(result.parameter_index)}
    out: dict[str, Float64Array] = {}
    for image, model in result.models.items():
        names = model.parameters.names
        rows = np.array([index.get((str(image), n), -1) for n in names], dtype=np.intp)
        full = np.zeros((len(names), len(names)))
        have = np.flatnonzero(rows >= 0)
        if have.size:
            full[np.ix_(have, have)] = cov[np.ix_(rows[have], rows[have])]
            out[str(image)] = full
    return out


def triangulate(
    models: Mapping[str, SensorModel],
    id: ArrayLike,
    image: ArrayLike,
    row: ArrayLike,
    col: ArrayLike,
    *,
    sigma_px: ArrayLike = 1.0,
    parameter_covariance: Mapping[str, ArrayLike] | None = None,
    tolerance_m: float = 1e-4,
    max_iterations: int = 10,
    step_m: float = 1.0,
    warn: bool = True,
) -> Triangulation:
    """Triangulate points from their measurements in two or more images.

    Parameters
    ----------
    models : mapping of str to SensorModel
        The model of each image, keyed by the image ids of ``image``. Any models: only
        ``backproject_with_status``, ``project_with_status``, ``height_range``,
        ``partials_ground`` and (with ``parameter_covariance``) ``partials_parameters`` are
        called.
    id, image : array_like of str, (K,)
        Point id and image id of each measurement.
    row, col : array_like, (K,)
        Measured image coordinates, pixels of the image's model (pixel centres at integers).
    sigma_px : float or array_like, (K,)
        Standard deviation of each measurement, pixels (both axes), for the covariance.
    parameter_covariance : mapping of str to array_like (P, P), optional
        Covariance of an image's model parameters (all ``P`` of ``model.parameters``, in
        their units), e.g. :func:`parameter_covariances` of a block adjustment; it adds
        ``A_p C A_p^T`` to the measurement covariance of that image's rays. Images not in the
        mapping contribute their image sigmas only.
    tolerance_m : float
        Converged when the point moves by at most this between two refinements, metres.
    max_iterations : int
        Cap on the refinements (step 3 of the module docstring).
    step_m : float
        Half the height interval the rays are re-taken over around the point, metres.
    warn : bool
        Emit one warning per failure status with its count.

    Returns
    -------
    Triangulation

    Raises
    ------
    ShapeMismatchError
        The measurement arrays differ in length.
    ObservationError
        A measurement names an image missing from ``models``, a point is measured twice in
        one image, a sigma is not positive, or an option is invalid.

    Examples
    --------
    >>> import geoblock
    >>> from geoblock.testing.synthetic import AffineCamera
    >>> from geoblock.triangulation import triangulate
    >>> a = AffineCamera.example()
    >>> b = a.with_parameters(a.parameters.values)  # the same camera: parallel rays
    >>> t = triangulate({"a": a, "b": b}, ["p", "p"], ["a", "b"], [500, 500], [600, 600],
    ...                 warn=False)
    >>> geoblock.Status(int(t.status[0])).name
    'NO_INTERSECTION'
    """
    where = "triangulate"
    if not (tolerance_m > 0 and math.isfinite(tolerance_m)):
        raise ObservationError(f"{where}: tolerance_m must be positive, got {tolerance_m!r}")
    if not (step_m > 0 and math.isfinite(step_m)):
        raise ObservationError(f"{where}: step_m must be positive, got {step_m!r}")
    if int(max_iterations) < 1:
        raise ObservationError(f"{where}: max_iterations must be >= 1, got {max_iterations!r}")
    ids, images, r, c = measurements(models, id, image, row, col, where)
    k = ids.shape[0]
    sig = _floats("sigma_px", sigma_px, k, where)
    if not (np.isfinite(sig) & (sig > 0)).all():
        bad = ids[~(np.isfinite(sig) & (sig > 0))][:5].tolist()
        raise ObservationError(f"{where}: sigma_px must be positive and finite (points {bad})")
    names = [str(m) for m in models]
    covs = {str(n): np.asarray(v, np.float64) for n, v in (parameter_covariance or {}).items()}
    for name, cov in covs.items():
        if name not in models:
            raise ObservationError(f"{where}: parameter_covariance names image {name!r}, which "
                                   f"is not in the models ({names})")
        p = len(models[name].parameters)
        if cov.shape != (p, p) or not np.isfinite(cov).all():
            raise ObservationError(f"{where}: parameter_covariance of image {name!r} must be a "
                                   f"finite ({p}, {p}) array (the model's {p} parameters), "
                                   f"got shape {cov.shape}")

    # points, in the order first met
    first_ids, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    point = rank[inverse.ravel()]
    point_ids = first_ids[order]
    n = point_ids.size

    # step 1: rays from the ends of each model's height range
    lo = np.empty(k)
    hi = np.empty(k)
    for name, model in models.items():
        sel = images == str(name)
        lo[sel], hi[sel] = (float(v) for v in model.height_range)
    valid = np.isfinite(r) & np.isfinite(c)
    origin, direction, ray_status = _rays(models, images, r, c, lo, hi)
    ray_status[~valid] = _INVALID
    status = np.full(n, _NO_INTERSECTION, np.uint8)
    xyz, ok = _intersect(origin, direction, ray_status == _OK, point, n)
    # a point whose rays failed carries the first failure of its models (else too few rays)
    failed = (ray_status != _OK) & (ray_status != _INVALID)
    worst = np.zeros(n, np.uint8)
    worst[point[failed]] = ray_status[failed]
    status[~ok] = np.where(worst[~ok] != 0, worst[~ok], _NO_INTERSECTION)
    status[ok] = _MAX_ITERATIONS

    # step 3: rays re-taken around the point's height until it stops moving
    active = np.flatnonzero(ok)
    for _ in range(int(max_iterations)):
        if active.size == 0:
            break
        g = coords.ecef_to_geodetic(xyz[active, 0], xyz[active, 1], xyz[active, 2])
        h_pt = np.full(n, np.nan)
        h_pt[active] = g.h
        meas = np.flatnonzero(np.isin(point, active) & (ray_status == _OK))
        hp = h_pt[point[meas]]
        o2, d2, s2 = _rays(models, images[meas], r[meas], c[meas], hp - step_m, hp + step_m)
        keep = s2 == _OK  # a ray that fails around the point keeps its previous line
        origin[meas[keep]], direction[meas[keep]] = o2[keep], d2[keep]
        new, ok2 = _intersect(origin, direction, ray_status == _OK, point, n)
        moved = np.linalg.norm(new[active] - xyz[active], axis=1)
        xyz[active] = np.where(ok2[active, None], new[active], xyz[active])
        done = ok2[active] & (moved <= tolerance_m)
        status[active[done]] = _OK
        lost = ~ok2[active]
        status[active[lost]] = _NO_INTERSECTION
        active = active[~done & ~lost]

    good = status == _OK
    lon = np.full(n, np.nan)
    lat = np.full(n, np.nan)
    h = np.full(n, np.nan)
    g = coords.ecef_to_geodetic(xyz[good, 0], xyz[good, 1], xyz[good, 2])
    lon[good], lat[good], h[good] = g.lon, g.lat, g.h

    # step 4: per ray distance, foot, residual; per point miss distance and covariance
    used = (ray_status == _OK) & good[point]
    rel = xyz[point] - origin
    along = np.einsum("ki,ki->k", rel, direction)
    foot = origin + along[:, None] * direction
    dist = np.linalg.norm(xyz[point] - foot, axis=1)
    dist[~used] = np.nan
    foot[~used] = np.nan
    rays = np.bincount(point[ray_status == _OK], minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        miss = 2.0 * np.sqrt(np.bincount(point[used], weights=dist[used] ** 2, minlength=n)
                             / np.bincount(point[used], minlength=n))
    miss[~good] = np.nan
    v_row = np.full(k, np.nan)
    v_col = np.full(k, np.nan)
    normal = np.zeros((n, 3, 3))
    for name, model in models.items():
        sel = np.flatnonzero(used & (images == str(name)))
        if sel.size == 0:
            continue
        pl, pa, ph = lon[point[sel]], lat[point[sel]], h[point[sel]]
        (rr, cc), _ = model.project_with_status(pl, pa, ph)
        v_row[sel], v_col[sel] = r[sel] - rr, c[sel] - cc
        a = np.asarray(model.partials_ground(pl, pa, ph), np.float64)  # (S, 2, 3)
        cov = np.eye(2)[None] * (sig[sel] ** 2)[:, None, None]
        if str(name) in covs:
            ap = np.asarray(model.partials_parameters(pl, pa, ph), np.float64)  # (S, 2, P)
            cov = cov + ap @ covs[str(name)] @ np.swapaxes(ap, -1, -2)
        w = np.linalg.inv(cov)
        contrib = np.swapaxes(a, -1, -2) @ w @ a  # (S, 3, 3)
        contrib[~np.isfinite(contrib).all(axis=(1, 2))] = np.nan
        np.add.at(normal, point[sel], contrib)
    covariance = np.full((n, 3, 3), np.nan)
    solvable = good & np.isfinite(normal).all(axis=(1, 2)) & (rays >= 2)
    if solvable.any():
        with np.errstate(invalid="ignore"):
            cond = np.linalg.cond(normal[solvable])
        inv_ok = np.flatnonzero(solvable)[cond < 1e12]
        cov_ecef = np.linalg.inv(normal[inv_ok])
        rot = coords.enu_rotation(lon[inv_ok], lat[inv_ok])  # (S, 3, 3) rows e, n, u
        covariance[inv_ok] = rot @ cov_ecef @ np.swapaxes(rot, -1, -2)
    if warn:
        warn_triangulation(status, where, stacklevel=3)
    return Triangulation(id=point_ids, lon=lon, lat=lat, h=h, miss_m=miss, rays=rays,
                         covariance=covariance, status=status, point=point, v_row=v_row,
                         v_col=v_col, distance_m=dist, foot=foot, ray_status=ray_status)


def warn_triangulation(status: np.ndarray, operation: str = "triangulate",
                       stacklevel: int = 2) -> None:
    """One warning per failure status of :func:`triangulate` with its count (``NO_INTERSECTION``
    said as triangulation means it: fewer than two rays, or parallel ones)."""
    import warnings

    from geoblock.errors import NoIntersectionWarning

    status = np.asarray(status, np.uint8)
    n = int(np.count_nonzero(status == _NO_INTERSECTION))
    if n:
        warnings.warn(f"{operation}: {n} of {status.size} points have fewer than two usable "
                      "rays or parallel ones (NO_INTERSECTION); they are NaN",
                      NoIntersectionWarning, stacklevel=stacklevel + 1)
    warn_status(np.where(status == _NO_INTERSECTION, _OK, status), operation,
                stacklevel=stacklevel + 1)


def _rays(models: Mapping[str, SensorModel], images: np.ndarray, row: Float64Array,
          col: Float64Array, h0: Float64Array, h1: Float64Array
          ) -> tuple[Float64Array, Float64Array, np.ndarray]:
    """ECEF origin (at ``h1``) and unit direction (towards ``h0``) of each measurement's
    ray, and the model's status (one vectorised call per image)."""
    k = row.size
    origin = np.full((k, 3), np.nan)
    direction = np.full((k, 3), np.nan)
    status = np.full(k, _INVALID, np.uint8)
    for name, model in models.items():
        sel = np.flatnonzero(images == str(name))
        if sel.size == 0:
            continue
        rr, cc = np.tile(row[sel], 2), np.tile(col[sel], 2)
        (lon, lat, h), st = model.backproject_with_status(rr, cc, np.concatenate([h1[sel],
                                                                                  h0[sel]]))
        xyz = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
        top, bottom = xyz[:sel.size], xyz[sel.size:]
        st = np.asarray(st, np.uint8)
        s = np.where(st[:sel.size] != _OK, st[:sel.size], st[sel.size:])
        d = bottom - top
        with np.errstate(invalid="ignore", divide="ignore"):
            d = d / np.linalg.norm(d, axis=1, keepdims=True)
        s = np.where((s == _OK) & ~np.isfinite(d).all(axis=1), _INVALID, s)
        origin[sel], direction[sel], status[sel] = top, d, s
    return origin, direction, status


def _intersect(origin: Float64Array, direction: Float64Array, use: np.ndarray,
               point: np.ndarray, n: int) -> tuple[Float64Array, np.ndarray]:
    """Least-squares point of each point's rays: ``(N, 3)`` ECEF and whether it is defined
    (two or more rays, not parallel)."""
    sel = np.flatnonzero(use)
    d = direction[sel]
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]  # (S, 3, 3)
    m = np.zeros((n, 3, 3))
    b = np.zeros((n, 3))
    np.add.at(m, point[sel], proj)
    np.add.at(b, point[sel], np.einsum("sij,sj->si", proj, origin[sel]))
    count = np.bincount(point[sel], minlength=n)
    ok = count >= 2
    xyz = np.full((n, 3), np.nan)
    if ok.any():
        eig = np.linalg.eigvalsh(m[ok])[:, 0]
        idx = np.flatnonzero(ok)
        fine = eig > _PARALLEL * count[idx]
        ok[idx[~fine]] = False
        idx = idx[fine]
        if idx.size:
            xyz[idx] = np.linalg.solve(m[idx], b[idx][..., None])[..., 0]
    return xyz, ok


def measurements(models: Mapping[str, Any], id: ArrayLike, image: ArrayLike, row: ArrayLike,
                 col: ArrayLike, where: str) -> tuple[np.ndarray, np.ndarray, Float64Array,
                                                      Float64Array]:
    """Image measurements checked: ``(id, image, row, col)`` as 1-D arrays of one length.

    Raises
    ------
    ShapeMismatchError
        The arrays are not one-dimensional of one length, or ``row``/``col`` not numeric.
    ObservationError
        A measurement names an image missing from ``models``, or a point is measured twice
        in one image (the message names them).
    """
    ids = np.atleast_1d(np.asarray(id)).astype(str)
    if ids.ndim != 1:
        raise ShapeMismatchError(f"{where}: id must be one-dimensional, got shape {ids.shape}")
    k = ids.shape[0]
    images = _strings("image", image, k, where)
    r = _floats("row", row, k, where)
    c = _floats("col", col, k, where)
    names = [str(m) for m in models]
    unknown = sorted(set(images.tolist()) - set(names))
    if unknown:
        raise ObservationError(f"{where}: measurements name image(s) {unknown} that are not in "
                               f"the models ({names})")
    keys = np.char.add(np.char.add(images, "\x1f"), ids)  # not NUL: numpy strips it
    uniq, counts = np.unique(keys, return_counts=True)
    if (counts > 1).any():
        dup = [u.replace("\x1f", ": ") for u in uniq[counts > 1][:5]]
        raise ObservationError(f"{where}: point(s) measured more than once in one image: {dup}")
    return ids, images, r, c


def _floats(name: str, value: ArrayLike, k: int, where: str) -> Float64Array:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeMismatchError(f"{where}: {name} must be numeric: {exc}") from exc
    if arr.ndim == 0:
        return np.full(k, float(arr))
    if arr.shape != (k,):
        raise ShapeMismatchError(f"{where}: {name} has shape {arr.shape}, expected ({k},)")
    return arr


def _strings(name: str, value: ArrayLike, k: int, where: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim == 0:
        return np.full(k, str(arr.item()), dtype=object).astype(str)
    if arr.shape != (k,):
        raise ShapeMismatchError(f"{where}: {name} has shape {arr.shape}, expected ({k},)")
    return arr.astype(str)
