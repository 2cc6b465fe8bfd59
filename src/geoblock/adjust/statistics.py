"""Accuracy statistics of control, check and tie points (Aguilar et al. 2007; Teo et al. 2010).

Definitions (errors are *estimated minus reference*; only finite errors count):

* ``RMSE_E = sqrt(mean(dE**2))``, ``RMSE_N = sqrt(mean(dN**2))``: metres along local east and
  north (Aguilar et al. write X and Y; their "RMSE_1D in X and Y" are these two);
* ``RMSE_2D = sqrt(RMSE_E**2 + RMSE_N**2)`` (Aguilar et al. eq. 5);
* ``RMSE_1D = RMSE_2D / sqrt(2)``: the quadratic mean of the two axes, the single
  one-dimensional figure quoted when one number per axis is wanted;
* mean error (bias) per axis; maximum error per axis *with its sign* (Aguilar et al. Table 3)
  and the largest 2D error ``max(sqrt(dE**2 + dN**2))``;
* ``n``: the number of points with finite errors.

Ground errors are measured in each reference point's local tangent plane (east, north, up
metres, :func:`geoblock.coords.enu_offsets`), so callers pass estimated and true
``lon, lat[, h]``. Image residuals are *observed minus computed*, pixels.

Point kinds (Teo et al.): ``GCP`` ground control point, ``ICP`` independent check point,
``TP`` tie point, ``ICTP`` independent check tie point (a tie point kept out of the
adjustment, used for the relative accuracy between images, :func:`ictp_accuracy`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from geoblock import coords
from geoblock.errors import ObservationError, ShapeMismatchError
from geoblock.typing import ArrayLike, Float64Array, IndexArray, Status, StatusArray, StrArray

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.models.protocol import SensorModel

__all__ = [
    "POINT_KINDS",
    "AccuracyStats",
    "ConfidenceInterval",
    "IctpDiscrepancies",
    "ImageResidualStats",
    "PointErrors",
    "confidence_interval",
    "distance_from_image_centre",
    "ground_errors",
    "ictp_accuracy",
]

#: the point kinds of Teo et al., in the order tables list them
POINT_KINDS = ("GCP", "ICP", "TP", "ICTP")


# --------------------------------------------------------------------------- helpers
def _signed_max(x: Float64Array) -> float:
    """The value of largest magnitude, with its sign (NaN for no values)."""
    return float(x[np.argmax(np.abs(x))]) if x.size else float("nan")


def _vector(name: str, value: ArrayLike, n: int | None = None, *, where: str) -> Float64Array:
    """``value`` as a 1-D float64 array of length ``n`` (a scalar is repeated)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeMismatchError(f"{where}: {name} must be numeric: {exc}") from exc
    if arr.ndim == 0 and n is not None:
        return np.full(n, float(arr))
    arr = arr.ravel() if arr.ndim > 1 and n is None else arr
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n):
        expected = f"({n},)" if n is not None else "one-dimensional"
        raise ShapeMismatchError(f"{where}: {name} has shape {arr.shape}, expected {expected}")
    return arr


def _labels(name: str, value: ArrayLike | None, n: int, *, where: str,
            default: str = "") -> StrArray:
    """``value`` as a 1-D array of ``n`` strings (a scalar or None is repeated)."""
    if value is None:
        return np.full(n, default, dtype=object).astype(str)
    arr = np.asarray(value)
    if arr.ndim == 0:
        return np.full(n, str(arr.item()), dtype=object).astype(str)
    if arr.shape != (n,):
        raise ShapeMismatchError(f"{where}: {name} has shape {arr.shape}, expected ({n},)")
    return arr.astype(str)


def _kinds(value: ArrayLike, n: int, *, where: str, ids: StrArray | None = None) -> StrArray:
    """Point kinds normalised to upper case; unknown kinds raise, naming the points."""
    kinds = np.char.upper(np.char.strip(_labels("kind", value, n, where=where)))
    bad = ~np.isin(kinds, POINT_KINDS)
    if bad.any():
        unknown = sorted(set(kinds[bad].tolist()))
        at = f" (points {', '.join(ids[bad][:5].tolist())})" if ids is not None else ""
        raise ObservationError(
            f"{where}: unknown point kind(s) {unknown}{at}; expected one of {list(POINT_KINDS)}"
        )
    return kinds


def _check_kind_names(kinds: Iterable[str], *, where: str) -> tuple[str, ...]:
    out = tuple(str(k).strip().upper() for k in kinds)
    bad = [k for k in out if k not in POINT_KINDS]
    if bad:
        raise ObservationError(
            f"{where}: unknown point kind(s) {bad}; expected one of {list(POINT_KINDS)}"
        )
    return out


# --------------------------------------------------------------------------- statistics
@dataclass(frozen=True)
class AccuracyStats:
    """RMSE, mean (bias) and maximum error of planimetric errors, metres.

    Errors are *estimated minus reference* along local east (E) and north (N). ``max_e`` and
    ``max_n`` keep their sign, as in Aguilar et al.'s Table 3; ``rmse_2d`` is
    ``sqrt(rmse_e**2 + rmse_n**2)`` (their eq. 5) and :attr:`rmse_1d` is
    ``rmse_2d / sqrt(2)``. Only finite error pairs count (``n``); with none every value is
    NaN.
    """

    n: int
    rmse_e: float
    rmse_n: float
    rmse_2d: float
    mean_e: float
    mean_n: float
    max_e: float
    max_n: float
    max_2d: float

    @property
    def rmse_1d(self) -> float:
        """``rmse_2d / sqrt(2)``, metres: the quadratic mean of ``rmse_e`` and ``rmse_n``."""
        return self.rmse_2d / math.sqrt(2.0)

    @classmethod
    def from_errors(cls, de: ArrayLike, dn: ArrayLike) -> AccuracyStats:
        """Statistics of the finite error pairs ``(de, dn)`` (metres, any equal shapes).

        Raises
        ------
        ShapeMismatchError
            ``de`` and ``dn`` have different shapes.
        """
        e_all = np.asarray(de, dtype=np.float64)
        n_all = np.asarray(dn, dtype=np.float64)
        if e_all.shape != n_all.shape:
            raise ShapeMismatchError(
                f"AccuracyStats.from_errors: de has shape {e_all.shape} but dn has shape "
                f"{n_all.shape}"
            )
        e_all, n_all = e_all.ravel(), n_all.ravel()
        ok = np.isfinite(e_all) & np.isfinite(n_all)
        e, n = e_all[ok], n_all[ok]
        if e.size == 0:
            nan = float("nan")
            return cls(0, nan, nan, nan, nan, nan, nan, nan, nan)
        rmse_e = float(np.sqrt(np.mean(e**2)))
        rmse_n = float(np.sqrt(np.mean(n**2)))
        return cls(
            n=int(e.size),
            rmse_e=rmse_e,
            rmse_n=rmse_n,
            rmse_2d=float(np.hypot(rmse_e, rmse_n)),
            mean_e=float(e.mean()),
            mean_n=float(n.mean()),
            max_e=_signed_max(e),
            max_n=_signed_max(n),
            max_2d=float(np.max(np.hypot(e, n))),
        )

    @classmethod
    def from_ground(
        cls,
        lon: ArrayLike,
        lat: ArrayLike,
        lon_ref: ArrayLike,
        lat_ref: ArrayLike,
        *,
        h: ArrayLike | None = None,
        h_ref: ArrayLike | None = None,
    ) -> AccuracyStats:
        """Statistics of estimated ground points against reference points (degrees, metres).

        See :func:`ground_errors` for the arguments.
        """
        de, dn, _ = ground_errors(lon, lat, lon_ref, lat_ref, h=h, h_ref=h_ref)
        return cls.from_errors(de, dn)

    def as_dict(self) -> dict[str, float | int]:
        """The fields and :attr:`rmse_1d` as a plain dictionary (for tables and JSON)."""
        out: dict[str, float | int] = asdict(self)
        out["rmse_1d"] = self.rmse_1d
        return out

    def as_row(self) -> str:
        """One line: ``n  RMSE E N 2D  max E N  mean E N`` (metres)."""
        return (
            f"{self.n:4d}  RMSE E {self.rmse_e:8.3f} N {self.rmse_n:8.3f} 2D {self.rmse_2d:8.3f}"
            f"  max E {self.max_e:8.3f} N {self.max_n:8.3f}"
            f"  mean E {self.mean_e:8.3f} N {self.mean_n:8.3f}"
        )


@dataclass(frozen=True)
class ImageResidualStats:
    """RMSE, mean and maximum of image residuals (observed minus computed), pixels.

    ``rmse_2d = sqrt(rmse_row**2 + rmse_col**2)``; ``max_row`` and ``max_col`` keep their
    sign; ``max_2d`` is the largest ``sqrt(row**2 + col**2)``. Only finite pairs count.
    """

    n: int
    rmse_row: float
    rmse_col: float
    rmse_2d: float
    mean_row: float
    mean_col: float
    max_row: float
    max_col: float
    max_2d: float

    @classmethod
    def from_residuals(cls, row: ArrayLike, col: ArrayLike) -> ImageResidualStats:
        """Statistics of the finite residual pairs ``(row, col)`` (pixels, equal shapes).

        Raises
        ------
        ShapeMismatchError
            ``row`` and ``col`` have different shapes.
        """
        rows = np.asarray(row, dtype=np.float64)
        cols = np.asarray(col, dtype=np.float64)
        if rows.shape != cols.shape:
            raise ShapeMismatchError(
                f"ImageResidualStats.from_residuals: row has shape {rows.shape} but col has "
                f"shape {cols.shape}"
            )
        a = AccuracyStats.from_errors(rows, cols)  # same arithmetic, other axes and units
        return cls(a.n, a.rmse_e, a.rmse_n, a.rmse_2d, a.mean_e, a.mean_n, a.max_e, a.max_n,
                   a.max_2d)

    def as_dict(self) -> dict[str, float | int]:
        """The fields as a plain dictionary."""
        return asdict(self)


def ground_errors(
    lon: ArrayLike,
    lat: ArrayLike,
    lon_ref: ArrayLike,
    lat_ref: ArrayLike,
    *,
    h: ArrayLike | None = None,
    h_ref: ArrayLike | None = None,
) -> tuple[Float64Array, Float64Array, Float64Array]:
    """Errors of estimated ground points against reference points, in metres east/north/up.

    Parameters
    ----------
    lon, lat : array_like, (*S,)
        Estimated points (e.g. check points located through an adjusted model), degrees.
    lon_ref, lat_ref : array_like, (*S,)
        Reference (true, surveyed) points, degrees.
    h, h_ref : array_like, (*S,), optional
        Heights above the WGS84 ellipsoid, metres. With only one of them, both points take
        it (a planimetric comparison) and ``du`` is NaN; without either both are 0, which
        scales E and N by about ``1 - h / 6.4e6`` (2e-4 at 1500 m).

    Returns
    -------
    de, dn, du : ndarray, (*S,)
        Estimated minus reference, metres along each reference point's local east, north and
        up (``du`` NaN unless both heights are given). NaN where an input is NaN.

    Raises
    ------
    ShapeMismatchError
        The arrays do not have the same shape.
    """
    arrays = {"lon": lon, "lat": lat, "lon_ref": lon_ref, "lat_ref": lat_ref}
    if h is not None:
        arrays["h"] = h
    if h_ref is not None:
        arrays["h_ref"] = h_ref
    conv = {k: np.asarray(v, dtype=np.float64) for k, v in arrays.items()}
    shapes = {k: v.shape for k, v in conv.items() if v.ndim}
    if len(set(shapes.values())) > 1:
        listed = ", ".join(f"{k} {s}" for k, s in shapes.items())
        raise ShapeMismatchError(f"ground_errors: the coordinate arrays differ in shape: {listed}")
    shape = next(iter(shapes.values()), ())
    hest = conv.get("h", conv.get("h_ref", 0.0))
    href = conv.get("h_ref", hest)
    de, dn, du = coords.enu_offsets(conv["lon_ref"], conv["lat_ref"], np.broadcast_to(href, shape),
                                    conv["lon"], conv["lat"], np.broadcast_to(hest, shape))
    if h is None or h_ref is None:
        du = np.full(np.shape(de), np.nan)
    return de, dn, du


# --------------------------------------------------------------------------- grouping
@dataclass(frozen=True, eq=False, init=False)
class PointErrors:
    """Per-point errors with their kind and image: the input of grouped statistics and tables.

    A structure of arrays, all ``(N,)``. Build it with :meth:`from_ground` (estimated and
    reference coordinates) or directly from errors.

    Parameters
    ----------
    id : array_like of str
        Point identifiers.
    kind : array_like of str or str
        ``GCP``, ``ICP``, ``TP`` or ``ICTP`` per point (case-insensitive).
    e, n : array_like
        Ground errors, estimated minus reference, metres along local east and north (NaN
        where unknown).
    u : array_like, optional
        Height errors, metres (default NaN).
    row, col : array_like, optional
        Image residuals, observed minus computed, pixels (default NaN).
    image : array_like of str or str, optional
        The image each measurement belongs to (default ``""``: one image or not per image).

    Raises
    ------
    ShapeMismatchError
        An array's length differs from ``id``'s.
    ObservationError
        An unknown point kind (the message names the points).
    """

    id: StrArray
    kind: StrArray
    e: Float64Array
    n: Float64Array
    u: Float64Array
    row: Float64Array
    col: Float64Array
    image: StrArray

    def __init__(
        self,
        id: ArrayLike,
        kind: ArrayLike,
        e: ArrayLike,
        n: ArrayLike,
        u: ArrayLike | None = None,
        row: ArrayLike | None = None,
        col: ArrayLike | None = None,
        image: ArrayLike | None = None,
    ) -> None:
        where = "PointErrors"
        ids = np.atleast_1d(np.asarray(id)).astype(str)
        if ids.ndim != 1:
            raise ShapeMismatchError(f"{where}: id must be one-dimensional, got shape {ids.shape}")
        size = ids.shape[0]
        values: dict[str, NDArray[Any]] = {
            "id": ids, "kind": _kinds(kind, size, where=where, ids=ids)}
        for name, raw in (("e", e), ("n", n), ("u", u), ("row", row), ("col", col)):
            values[name] = (np.full(size, np.nan) if raw is None
                            else _vector(name, raw, size, where=where))
        values["image"] = _labels("image", image, size, where=where)
        for name, arr in values.items():
            arr = np.array(arr)
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @classmethod
    def from_ground(
        cls,
        id: ArrayLike,
        kind: ArrayLike,
        lon: ArrayLike,
        lat: ArrayLike,
        lon_ref: ArrayLike,
        lat_ref: ArrayLike,
        *,
        h: ArrayLike | None = None,
        h_ref: ArrayLike | None = None,
        image: ArrayLike | None = None,
        row: ArrayLike | None = None,
        col: ArrayLike | None = None,
    ) -> PointErrors:
        """Errors from estimated and reference ground coordinates (see :func:`ground_errors`)."""
        n = np.atleast_1d(np.asarray(id)).shape[0]
        args = {"lon": lon, "lat": lat, "lon_ref": lon_ref, "lat_ref": lat_ref}
        for name, value in args.items():
            _vector(name, value, n, where="PointErrors.from_ground")
        de, dn, du = ground_errors(lon, lat, lon_ref, lat_ref, h=h, h_ref=h_ref)
        return cls(id, kind, de, dn, du, row, col, image)

    def select(self, *, kind: str | Iterable[str] | None = None,
               image: str | Iterable[str] | None = None) -> PointErrors:
        """The points of the given kind(s) and/or image(s) (possibly none)."""
        mask = np.ones(len(self), dtype=bool)
        if kind is not None:
            kinds = _check_kind_names([kind] if isinstance(kind, str) else kind,
                                      where="PointErrors.select")
            mask &= np.isin(self.kind, kinds)
        if image is not None:
            images = [image] if isinstance(image, str) else [str(i) for i in image]
            mask &= np.isin(self.image, images)
        return PointErrors(self.id[mask], self.kind[mask], self.e[mask], self.n[mask],
                           self.u[mask], self.row[mask], self.col[mask], self.image[mask])

    # ---- statistics
    def stats(self) -> AccuracyStats:
        """Ground statistics of all the points."""
        return AccuracyStats.from_errors(self.e, self.n)

    def residual_stats(self) -> ImageResidualStats:
        """Image residual statistics of all the points."""
        return ImageResidualStats.from_residuals(self.row, self.col)

    def by_kind(self, kinds: Sequence[str] | None = None, *, image_space: bool = False,
                ) -> dict[str, AccuracyStats] | dict[str, ImageResidualStats]:
        """Statistics per point kind.

        Parameters
        ----------
        kinds : sequence of str, optional
            The kinds wanted, in this order; each must have points. Default: the kinds
            present, in :data:`POINT_KINDS` order.
        image_space : bool
            Image residual statistics (pixels) instead of ground statistics (metres).

        Raises
        ------
        ObservationError
            A requested kind is unknown or has no point.
        """
        return self._grouped((self.kind,), None if kinds is None else
                             [(k,) for k in _check_kind_names(kinds, where="PointErrors.by_kind")],
                             image_space, key_single=True, order=[(k,) for k in POINT_KINDS])

    def by_image(self, images: Sequence[str] | None = None, *, image_space: bool = False,
                 ) -> dict[str, AccuracyStats] | dict[str, ImageResidualStats]:
        """Statistics per image (default: the images present, sorted). See :meth:`by_kind`."""
        wanted = None if images is None else [(str(i),) for i in images]
        return self._grouped((self.image,), wanted, image_space, key_single=True)

    def by_image_and_kind(self, *, image_space: bool = False,
                          ) -> dict[tuple[str, str], AccuracyStats | ImageResidualStats]:
        """Statistics per ``(image, kind)`` pair present (images sorted, kinds in order)."""
        pairs = set(zip(self.image.tolist(), self.kind.tolist(), strict=True))
        order = sorted(pairs, key=lambda ik: (ik[0], POINT_KINDS.index(ik[1])))
        return self._grouped((self.image, self.kind), None, image_space, key_single=False,
                             order=order)

    def _grouped(
        self,
        columns: tuple[StrArray, ...],
        wanted: Sequence[tuple[str, ...]] | None,
        image_space: bool,
        *,
        key_single: bool,
        order: Sequence[tuple[str, ...]] | None = None,
    ) -> dict[Any, Any]:
        keys: list[tuple[str, ...]] = list(zip(*(c.tolist() for c in columns), strict=True))
        present = set(keys)
        if wanted is None:
            wanted = ([k for k in order if k in present] if order is not None
                      else sorted(present))
        else:
            missing = [k for k in wanted if k not in present]
            if missing:
                names = [m[0] if key_single else m for m in missing]
                raise ObservationError(
                    f"PointErrors: no point in group(s) {names}; present: "
                    f"{sorted(k[0] if key_single else k for k in present)}"
                )
        stacked = np.array(keys, dtype=object).reshape(len(keys), len(columns))
        out: dict[Any, Any] = {}
        for key in wanted:
            mask = np.all(stacked == np.array(key, dtype=object), axis=1)
            value: AccuracyStats | ImageResidualStats
            if image_space:
                value = ImageResidualStats.from_residuals(self.row[mask], self.col[mask])
            else:
                value = AccuracyStats.from_errors(self.e[mask], self.n[mask])
            out[key[0] if key_single else tuple(key)] = value
        return out


# --------------------------------------------------------------------------- ICTP
@dataclass(frozen=True, eq=False)
class IctpDiscrepancies:
    """Discrepancies between the ground positions of the same tie points seen in two images.

    One entry per point and pair of images that measured it, all arrays ``(M,)``. Image
    ``a`` comes before image ``b`` in the order of the ``models`` mapping given to
    :func:`ictp_accuracy`.

    Attributes
    ----------
    id, image_a, image_b : ndarray of str
    lon_a, lat_a, h_a, lon_b, lat_b, h_b : ndarray
        The measurement of each image ray-traced onto the DEM (or, without a DEM, the point
        of its ray nearest the other ray), degrees and metres above the ellipsoid (NaN where
        it failed).
    e, n, u : ndarray
        Point from image ``b`` minus point from image ``a``, metres along local east, north
        and up at point ``a``.
    status_a, status_b : ndarray of uint8
        :class:`~geoblock.typing.Status` of each ray tracing (without a DEM: of the pair's
        triangulation).
    unpaired : ndarray of str
        Points measured in a single image (no discrepancy; not in the arrays above).
    """

    id: StrArray
    image_a: StrArray
    image_b: StrArray
    lon_a: Float64Array
    lat_a: Float64Array
    h_a: Float64Array
    lon_b: Float64Array
    lat_b: Float64Array
    h_b: Float64Array
    e: Float64Array
    n: Float64Array
    u: Float64Array
    status_a: StatusArray
    status_b: StatusArray
    unpaired: StrArray

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @property
    def distance_2d(self) -> Float64Array:
        """(M,) horizontal distance between the two ground points, metres."""
        return np.hypot(self.e, self.n)

    @property
    def distance_3d(self) -> Float64Array:
        """(M,) 3D distance between the two ground points, metres."""
        return np.sqrt(self.e**2 + self.n**2 + self.u**2)

    @property
    def stats(self) -> AccuracyStats:
        """Statistics of the ``(e, n)`` discrepancies: Teo et al.'s ICTP RMSE E and N."""
        return AccuracyStats.from_errors(self.e, self.n)

    @property
    def rmse_3d(self) -> float:
        """RMS of the finite 3D distances, metres (NaN if none)."""
        d = self.distance_3d
        d = d[np.isfinite(d)]
        return float(np.sqrt(np.mean(d**2))) if d.size else float("nan")

    def by_pair(self) -> dict[tuple[str, str], AccuracyStats]:
        """Statistics per image pair ``(image_a, image_b)``, in the order first met."""
        pairs = list(dict.fromkeys(zip(self.image_a.tolist(), self.image_b.tolist(), strict=True)))
        return {
            (a, b): AccuracyStats.from_errors(*(x[(self.image_a == a) & (self.image_b == b)]
                                                for x in (self.e, self.n)))
            for a, b in pairs
        }

    def as_point_errors(self) -> PointErrors:
        """The discrepancies as :class:`PointErrors` of kind ``ICTP``, image ``"a & b"``."""
        image = np.char.add(np.char.add(self.image_a.astype(str), " & "), self.image_b.astype(str))
        return PointErrors(self.id, "ICTP", self.e, self.n, self.u, image=image)


def ictp_accuracy(
    models: Mapping[str, SensorModel],
    id: ArrayLike,
    image: ArrayLike,
    row: ArrayLike,
    col: ArrayLike,
    dem: DemSource | float | None,
    **localize_options: Any,
) -> IctpDiscrepancies:
    """Relative accuracy between images at independent check tie points (Teo et al. 2010).

    Each image measurement of an ICTP is ray-traced onto the DEM through its image's model
    (:func:`geoblock.localize`); for every pair of images measuring the same point, the
    discrepancy is the vector between the two ground points. Teo et al. report its RMSE
    along E and N (:attr:`IctpDiscrepancies.stats`); the horizontal and 3D distances are
    :attr:`~IctpDiscrepancies.distance_2d` and :attr:`~IctpDiscrepancies.distance_3d`.

    With ``dem=None`` the pairs are triangulated instead (:func:`geoblock.triangulation.
    triangulate`, no DEM): the two ground points of a pair are the ends of the common
    perpendicular of its two rays, so the discrepancy is the rays' miss vector (its length
    the pair's miss distance), free of the DEM's height errors, which the DEM route turns into
    horizontal discrepancies along the rays' parallax.

    Parameters
    ----------
    models : mapping of str to SensorModel
        The (adjusted) model of each image, keyed by image name. The mapping's order decides
        which image of a pair is ``a``.
    id, image : array_like of str, (K,)
        Point identifier and image name of each measurement.
    row, col : array_like, (K,)
        Measured image coordinates, pixels.
    dem : DemSource, float or None
        Terrain heights above the ellipsoid (a number means a constant height); None
        triangulates each pair of rays instead.
    **localize_options
        Passed to :func:`geoblock.localize` (``method``, ``tolerance_m``, ``warn`` ...), or
        with ``dem=None`` to :func:`~geoblock.triangulation.triangulate` (``tolerance_m``,
        ``max_iterations``, ``warn`` ...).

    Returns
    -------
    IctpDiscrepancies

    Raises
    ------
    ShapeMismatchError
        The measurement arrays differ in length.
    ObservationError
        A measurement names an image missing from ``models``, a point is measured twice in
        the same image, or no point is measured in two images.
    """
    from geoblock.dem import localize  # geoblock.dem imports nothing from adjust; keep it lazy
    from geoblock.triangulation import measurements  # same layer; lazy like localize
    from geoblock.adjust.normal import measurement_pairs
    from geoblock.adjust.observations import lookup

    where = "ictp_accuracy"
    ids, images, r, c = measurements(models, id, image, row, col, where)
    k = ids.shape[0]

    # ray-trace each image's measurements (one vectorised call per image)
    lon = np.full(k, np.nan)
    lat = np.full(k, np.nan)
    h = np.full(k, np.nan)
    status = np.full(k, np.uint8(Status.INVALID_INPUT), dtype=np.uint8)
    names = [str(m) for m in models]
    # the measurements grouped by image once (no scan of every measurement per image)
    rank = lookup(np.array(names, dtype=str), images)  # each measurement's image, models' order
    by_image = np.argsort(rank, kind="stable")
    starts = np.searchsorted(rank[by_image], np.arange(len(names) + 1))
    if dem is not None:
        for i, model in enumerate(models.values()):
            sel = by_image[starts[i]:starts[i + 1]]
            if sel.size:
                g, s = localize(model, r[sel], c[sel], dem, **localize_options)
                lon[sel], lat[sel], h[sel], status[sel] = g.lon, g.lat, g.h, s

    # every pair of images measuring the same point, in the models' order (a before b), then
    # by point id: each point's measurements paired among themselves, not every pair of images
    point_ids, point = np.unique(ids, return_inverse=True)
    pairs = measurement_pairs(point.ravel(), point_ids.size)
    first = rank[pairs.a] < rank[pairs.b]
    a, b = pairs.a[first], pairs.b[first]
    order = np.lexsort((point.ravel()[a], rank[b], rank[a]))
    a, b = a[order].astype(np.intp), b[order].astype(np.intp)
    if a.size == 0:
        raise ObservationError(f"{where}: no point is measured in two images; ICTPs need a "
                               "measurement in each of at least two images")
    paired = np.union1d(ids[a], ids[b])
    lon_a, lat_a, h_a, status_a = lon[a], lat[a], h[a], status[a]
    lon_b, lat_b, h_b, status_b = lon[b], lat[b], h[b], status[b]
    if dem is None:  # each pair triangulated: the ends of its rays' common perpendicular
        lon_a, lat_a, h_a, status_a, lon_b, lat_b, h_b, status_b = _pair_feet(
            models, images, r, c, a, b, **localize_options)
    de, dn, du = coords.enu_offsets(lon_a, lat_a, h_a, lon_b, lat_b, h_b)
    return IctpDiscrepancies(
        id=ids[a], image_a=images[a], image_b=images[b],
        lon_a=lon_a, lat_a=lat_a, h_a=h_a, lon_b=lon_b, lat_b=lat_b, h_b=h_b,
        e=de, n=dn, u=du, status_a=status_a, status_b=status_b,
        unpaired=np.setdiff1d(np.unique(ids), paired),
    )


def _pair_feet(models: Mapping[str, SensorModel], images: StrArray, r: Float64Array,
               c: Float64Array, a: IndexArray, b: IndexArray, **options: Any
               ) -> tuple[NDArray[Any], ...]:
    """Triangulate each pair ``(a[j], b[j])`` of measurements alone; the feet of the point
    on ray a and ray b (lon, lat, h) and the pair's status, twice."""
    from geoblock.triangulation import triangulate  # same layer; lazy like localize

    m = a.size
    pair = np.concatenate([np.arange(m), np.arange(m)]).astype(str)
    both = np.concatenate([a, b])
    t = triangulate(models, pair, images[both], r[both], c[both], **options)
    feet = coords.ecef_to_geodetic(t.foot[:, 0], t.foot[:, 1], t.foot[:, 2])
    status = t.status[t.point]
    out: list[NDArray[Any]] = []
    for half in (slice(0, m), slice(m, 2 * m)):
        out += [feet.lon[half], feet.lat[half], feet.h[half], status[half]]
    return tuple(out)


# --------------------------------------------------------------------------- geometry helper
def distance_from_image_centre(model: SensorModel, lon: ArrayLike, lat: ArrayLike,
                               h: ArrayLike) -> Float64Array:
    """Planimetric distance of ground points from the image centre, metres (Aguilar Fig. 4).

    The centre pixel ``((rows - 1) / 2, (cols - 1) / 2)`` is backprojected at each point's
    own height, so relief does not enter the distance.

    Parameters
    ----------
    model : SensorModel
    lon, lat : array_like, (*S,)
        Degrees.
    h : array_like, (*S,)
        Metres above the ellipsoid.

    Returns
    -------
    ndarray, (*S,)
        Metres; NaN where the centre cannot be backprojected at that height.
    """
    lon_, lat_, h_ = (np.asarray(v, dtype=np.float64) for v in (lon, lat, h))
    rows, cols = model.shape
    centre, _ = model.backproject_with_status((rows - 1) / 2.0, (cols - 1) / 2.0, h_)
    de, dn, _ = coords.enu_offsets(centre.lon, centre.lat, centre.h, lon_, lat_, h_)
    return np.hypot(de, dn)


# --------------------------------------------------------------------------- repetitions
@dataclass(frozen=True)
class ConfidenceInterval:
    """A confidence interval over repetitions (e.g. Monte-Carlo runs), per column.

    Attributes
    ----------
    mean, low, high, std : float or ndarray, (K,)
        Mean of the finite values, the interval's bounds and the sample standard deviation
        (``ddof=1``), in the values' units.
    n : int or ndarray of int, (K,)
        Finite values per column.
    level : float
        Confidence level, e.g. 0.95.
    method : str
        ``"t"`` or ``"percentile"`` (see :func:`confidence_interval`).
    """

    mean: float | Float64Array
    low: float | Float64Array
    high: float | Float64Array
    std: float | Float64Array
    n: int | NDArray[np.intp]
    level: float
    method: str


def confidence_interval(values: ArrayLike, *, level: float = 0.95, method: str = "t",
                        ) -> ConfidenceInterval:
    """Mean and confidence interval of a statistic over repetitions.

    Parameters
    ----------
    values : array_like, (R,) or (R, K)
        ``R`` repetitions (rows) of ``K`` statistics, e.g. ICP ``RMSE_2D`` of ``R``
        Monte-Carlo runs for ``K`` GCP counts. Non-finite values are ignored per column.
    level : float
        Confidence level in (0, 1).
    method : {"t", "percentile"}
        ``"t"``: the Student-t interval of the *mean*, ``mean +- t(1 - (1-level)/2, n-1) *
        std / sqrt(n)`` (Aguilar et al.'s error bars, Fig. 6); NaN bounds for fewer than two
        values. ``"percentile"``: the empirical interval holding the central ``level`` of the
        *runs*, ``percentile(values, [50 (1-level), 50 (1+level)])`` (the spread one run can
        show).

    Returns
    -------
    ConfidenceInterval
        Scalars for 1-D ``values``, ``(K,)`` arrays for 2-D ones.

    Raises
    ------
    ShapeMismatchError
        ``values`` is not 1-D or 2-D, or has no repetition.
    ObservationError
        ``level`` outside (0, 1) or an unknown ``method``.
    """
    from scipy import stats as _stats

    where = "confidence_interval"
    if not 0.0 < float(level) < 1.0:
        raise ObservationError(f"{where}: level must be in (0, 1), got {level!r}")
    if method not in ("t", "percentile"):
        raise ObservationError(f"{where}: method must be 't' or 'percentile', got {method!r}")
    v = np.asarray(values, dtype=np.float64)
    if v.ndim not in (1, 2) or v.shape[0] == 0:
        raise ShapeMismatchError(
            f"{where}: values must be (R,) or (R, K) with R >= 1 repetitions, got shape {v.shape}"
        )
    scalar = v.ndim == 1
    v = v.reshape(v.shape[0], -1)
    ok = np.isfinite(v)
    n = ok.sum(axis=0)
    filled = np.where(ok, v, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = filled.sum(axis=0) / n
        ss = np.where(ok, (v - mean) ** 2, 0.0).sum(axis=0)
        std = np.where(n > 1, np.sqrt(ss / np.maximum(n - 1, 1)), np.nan)
    mean = np.where(n > 0, mean, np.nan)
    if method == "t":
        q = _stats.t.ppf(0.5 + level / 2.0, np.maximum(n - 1, 1))
        half = np.where(n > 1, q * std / np.sqrt(np.maximum(n, 1)), np.nan)
        low, high = mean - half, mean + half
    else:
        low = np.full(v.shape[1], np.nan)
        high = np.full(v.shape[1], np.nan)
        for j in np.flatnonzero(n > 0):  # per column: K is small (a few GCP counts)
            low[j], high[j] = np.percentile(v[ok[:, j], j], [50 * (1 - level), 50 * (1 + level)])

    def out(x: Float64Array) -> float | Float64Array:
        return float(x.item()) if scalar else x

    return ConfidenceInterval(out(mean), out(low), out(high), out(std),
                              int(n[0]) if scalar else n, float(level), method)
