"""Observations: ground control with image measurements, as structures of arrays."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from geoblock.errors import ObservationError
from geoblock.typing import ArrayLike, BoolArray, Float64Array, IndexArray, StrArray

__all__ = ["DEFAULT_SOURCE", "GROUND_KINDS", "KINDS", "ControlPoints", "GroundPoints",
           "ImagePoints"]


@dataclass(frozen=True, eq=False, init=False)
class ControlPoints:
    """Ground points with their measured positions in one image (GCPs or ICPs).

    Parameters
    ----------
    id : array_like of str, (N,)
        Point identifiers (named in error messages and reports).
    lon, lat : array_like, (N,)
        Ground coordinates, degrees (WGS84).
    h : array_like, (N,)
        Height above the WGS84 ellipsoid, metres.
    row, col : array_like, (N,)
        Measured image coordinates, pixels (pixel-centre convention).
    sigma_row, sigma_col : array_like, (N,) or scalar
        Standard deviation of the image measurements, pixels (default 0.5, Teo et al.).
    sigma_e, sigma_n, sigma_h : array_like, (N,) or scalar
        Standard deviation of the ground coordinates along local east, north and up, metres
        (default 0: error-free ground).
    """

    id: StrArray
    lon: Float64Array
    lat: Float64Array
    h: Float64Array
    row: Float64Array
    col: Float64Array
    sigma_row: Float64Array
    sigma_col: Float64Array
    sigma_e: Float64Array
    sigma_n: Float64Array
    sigma_h: Float64Array

    def __init__(
        self,
        id: ArrayLike,
        lon: ArrayLike,
        lat: ArrayLike,
        h: ArrayLike,
        row: ArrayLike,
        col: ArrayLike,
        sigma_row: ArrayLike = 0.5,
        sigma_col: ArrayLike = 0.5,
        sigma_e: ArrayLike = 0.0,
        sigma_n: ArrayLike = 0.0,
        sigma_h: ArrayLike = 0.0,
    ) -> None:
        ids = np.atleast_1d(np.asarray(id)).astype(str)
        n = ids.shape[0]
        if ids.ndim != 1:
            raise ObservationError(
                f"ControlPoints: id must be one-dimensional, got shape {ids.shape}"
            )
        object.__setattr__(self, "id", ids)
        given = {"lon": lon, "lat": lat, "h": h, "row": row, "col": col,
                 "sigma_row": sigma_row, "sigma_col": sigma_col, "sigma_e": sigma_e,
                 "sigma_n": sigma_n, "sigma_h": sigma_h}
        for name, value in given.items():
            raw = np.asarray(value, dtype=np.float64)
            if raw.ndim == 0:
                raw = np.full(n, float(raw))
            if raw.shape != (n,):
                raise ObservationError(
                    f"ControlPoints: {name} has shape {raw.shape}, expected ({n},) like id"
                )
            bad = ~np.isfinite(raw)
            if name.startswith("sigma"):
                positive = name in ("sigma_row", "sigma_col")
                bad |= (raw <= 0) if positive else (raw < 0)
            if bad.any():
                which = ", ".join(ids[bad][:5]) + (" ..." if bad.sum() > 5 else "")
                rule = "finite and > 0" if name in ("sigma_row", "sigma_col") else (
                    "finite and >= 0" if name.startswith("sigma") else "finite")
                raise ObservationError(f"ControlPoints: {name} must be {rule} (points {which})")
            raw.flags.writeable = False
            object.__setattr__(self, name, raw)
        dup = {i for i in ids.tolist() if (ids == i).sum() > 1}
        if dup:
            raise ObservationError(f"ControlPoints: duplicate point ids {sorted(dup)}")

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @classmethod
    def from_columns(cls, columns: Mapping[str, ArrayLike], **defaults: float) -> ControlPoints:
        """Build from a column mapping such as :func:`geoblock.io.read_points` returns.

        Columns ``id, lon, lat, h, row, col`` are required; ``sigma_*`` columns are optional
        (``defaults`` override the class defaults for absent ones).
        """
        missing = [c for c in ("lon", "lat", "h", "row", "col") if c not in columns]
        if missing:
            raise ObservationError(f"control points need columns {missing}")
        kwargs: dict[str, ArrayLike] = {
            f.name: columns[f.name] for f in fields(cls) if f.name in columns}
        for name, value in defaults.items():
            kwargs.setdefault(name, value)
        if "id" not in kwargs:
            kwargs["id"] = [str(i + 1) for i in range(len(np.asarray(columns["lon"])))]
        return cls(**kwargs)

    def subset(self, mask: ArrayLike) -> ControlPoints:
        """The points selected by a boolean mask or index array."""
        mask = np.asarray(mask)
        return ControlPoints(**{f.name: getattr(self, f.name)[mask] for f in fields(self)})


KINDS = ("gcp", "icp", "tp", "ictp", "hcp")
"""Point kinds: ground control (GCP), independent check (ICP), tie (TP), independent check
tie point (ICTP) and height control point (HCP: a tie point whose height is observed). GCPs,
TPs and HCPs enter an adjustment; ICPs and ICTPs are only evaluated."""

#: kinds of the ground CSV's rows
GROUND_KINDS = ("gcp", "icp", "hcp")
#: the ``source`` of a ground row that does not say
DEFAULT_SOURCE = "survey"


def _text(value: ArrayLike, n: int | None, name: str, where: str) -> StrArray:
    out = np.asarray(value).astype(str)
    if out.ndim == 0:
        out = np.full(1 if n is None else n, str(out))
    if out.ndim != 1 or (n is not None and out.shape != (n,)):
        raise ObservationError(f"{where}: {name} has shape {out.shape}, expected ({n},)")
    return out


def _floats(value: ArrayLike, n: int, name: str, where: str) -> Float64Array:
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ObservationError(f"{where}: {name} must be numbers") from None
    if out.ndim == 0:
        out = np.full(n, float(out))
    if out.shape != (n,):
        raise ObservationError(f"{where}: {name} has shape {out.shape}, expected ({n},)")
    return out


def lookup(table: ArrayLike, keys: ArrayLike) -> IndexArray:
    """Index of each of ``keys`` in the 1-D array ``table`` of unique strings; -1 if absent."""
    table = np.asarray(table)
    keys = np.asarray(keys)
    if table.size == 0:
        return np.full(keys.shape, -1, np.intp)
    order = np.argsort(table, kind="stable")
    pos = np.clip(np.searchsorted(table[order], keys), 0, table.size - 1)
    hit = table[order][pos] == keys
    return np.where(hit, order[pos], -1).astype(np.intp)


def _name_points(ids: StrArray, bad: BoolArray) -> str:
    listed = ", ".join(ids[bad][:5].tolist())
    return listed + (f" and {int(bad.sum()) - 5} more" if bad.sum() > 5 else "")


@dataclass(frozen=True, eq=False, init=False)
class GroundPoints:
    """Ground points of a block, one row per point (the ground CSV of a block).

    Parameters
    ----------
    id : array_like of str, (N,)
        Unique point identifiers (the ``id`` column of the image measurements refers to them).
    kind : array_like of str, (N,)
        ``gcp`` (enters the adjustment as a weighted observation of the point's east, north
        and up), ``icp`` (independent check point: only evaluated) or ``hcp`` (height control
        point: only ``h`` is an observation, of a tie point's height).
    lon, lat : array_like, (N,)
        Degrees (WGS84). An ``hcp`` may leave them NaN; when given they are only its initial
        position, never an observation.
    h : array_like, (N,)
        Metres above the WGS84 ellipsoid.
    sigma_e, sigma_n, sigma_h : array_like, (N,) or scalar
        Standard deviations of each point's own (independent) error along local east, north
        and up, metres (0: error-free; the adjustment floors them at 1 mm). An ``hcp`` needs
        a finite ``sigma_h > 0``.
    source : array_like of str, (N,) or str
        Where the coordinates come from (default ``"survey"``; a reference orthoimage's
        control carries ``"reference:<file name>"``). Reports give statistics per source.
    sigma_shift_e, sigma_shift_n, sigma_shift_h : array_like, (N,) or scalar
        Standard deviation of an error common to all points of the same ``source`` (e.g. a
        reference orthoimage's misregistration) along local east, north and up at the
        source's centroid, metres; equal within a source (0: none). The adjustment estimates
        that common shift (:attr:`~geoblock.adjust.BlockResult.shifts`).

    Raises
    ------
    ObservationError
        An unknown kind, a non-finite coordinate (a GCP/ICP without ``lon``/``lat``), a
        negative sigma, an HCP whose ``sigma_h`` is not finite and > 0, duplicate ids, or
        shift sigmas that differ within a source (the message names the points or source).
    """

    id: StrArray
    kind: StrArray
    lon: Float64Array
    lat: Float64Array
    h: Float64Array
    sigma_e: Float64Array
    sigma_n: Float64Array
    sigma_h: Float64Array
    source: StrArray
    sigma_shift_e: Float64Array
    sigma_shift_n: Float64Array
    sigma_shift_h: Float64Array

    def __init__(
        self,
        id: ArrayLike,
        kind: ArrayLike,
        lon: ArrayLike,
        lat: ArrayLike,
        h: ArrayLike,
        sigma_e: ArrayLike = 0.0,
        sigma_n: ArrayLike = 0.0,
        sigma_h: ArrayLike = 0.0,
        source: ArrayLike = DEFAULT_SOURCE,
        sigma_shift_e: ArrayLike = 0.0,
        sigma_shift_n: ArrayLike = 0.0,
        sigma_shift_h: ArrayLike = 0.0,
    ) -> None:
        where = "ground points"
        ids = _text(id, None, "id", where)
        n = ids.shape[0]
        kind = np.char.lower(np.char.strip(_text(kind, n, "kind", where)))
        bad = ~np.isin(kind, GROUND_KINDS)
        if bad.any():
            raise ObservationError(
                f"{where}: kind must be 'gcp', 'icp' or 'hcp' (points {_name_points(ids, bad)} "
                f"have {sorted(set(kind[bad].tolist()))}); tie points have no ground "
                "coordinates")
        hcp = kind == "hcp"
        src = np.char.strip(_text(source, n, "source", where))
        src = np.where(src == "", DEFAULT_SOURCE, src)
        given = {"lon": lon, "lat": lat, "h": h, "sigma_e": sigma_e, "sigma_n": sigma_n,
                 "sigma_h": sigma_h, "sigma_shift_e": sigma_shift_e,
                 "sigma_shift_n": sigma_shift_n, "sigma_shift_h": sigma_shift_h}
        values = {}
        for name, value in given.items():
            arr = _floats(value, n, name, where)
            bad = ~np.isfinite(arr)
            if name in ("lon", "lat"):
                bad &= ~hcp  # an HCP's planimetry is optional (only an initial position)
            if name.startswith("sigma"):
                bad |= arr < 0
                if name == "sigma_h":
                    bad &= ~hcp  # an HCP's sigma_h has its own rule, below
            elif name == "lat":
                bad |= np.abs(arr) > 90
            elif name == "lon":
                bad |= np.abs(arr) > 360
            elif name == "h":
                bad |= np.abs(arr) > 1e5
            if bad.any():
                rule = "finite and >= 0" if name.startswith("sigma") else "a finite coordinate"
                raise ObservationError(f"{where}: {name} must be {rule} (points "
                                       f"{_name_points(ids, bad)})")
            arr.flags.writeable = False
            values[name] = arr
        bad = hcp & ~(values["sigma_h"] > 0)
        if bad.any():
            raise ObservationError(
                f"{where}: a height control point (kind hcp) needs a finite sigma_h > 0, the "
                f"accuracy of its height (points {_name_points(ids, bad)})")
        bad = hcp & (np.isfinite(values["lon"]) != np.isfinite(values["lat"]))
        if bad.any():
            raise ObservationError(f"{where}: lon and lat must be both given or both empty "
                                   f"(points {_name_points(ids, bad)})")
        unique, counts = np.unique(ids, return_counts=True)
        if (counts > 1).any():
            dup = unique[counts > 1][:5].tolist()
            raise ObservationError(f"{where}: duplicate point ids {dup}")
        shift = np.stack([values[f"sigma_shift_{a}"] for a in "enh"], -1)
        names, inverse = np.unique(src, return_inverse=True)
        for k in np.flatnonzero([np.ptp(shift[inverse == i], axis=0).max(initial=0.0) > 0
                                 for i in range(names.size)]):
            rows = inverse == k
            raise ObservationError(
                f"{where}: sigma_shift_e/n/h are the error common to all points of a source, "
                f"so they must be equal within it; source {str(names[k])!r} has "
                f"{sorted({tuple(r) for r in shift[rows].tolist()})[:4]} (points "
                f"{_name_points(ids, rows)})")
        for name, text in (("id", ids), ("kind", kind), ("source", src)):
            text = np.asarray(text).astype(str)
            text.flags.writeable = False
            object.__setattr__(self, name, text)
        for name, arr in values.items():
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @classmethod
    def from_columns(cls, columns: Mapping[str, ArrayLike], *, source: str = "ground points",
                     kind: str = "gcp") -> GroundPoints:
        """From the columns of a ground CSV (:func:`geoblock.io.read_points`).

        ``id, h`` are required, and ``lon, lat`` unless every row is an ``hcp`` (absent:
        NaN); ``sigma_e, sigma_n, sigma_h`` and ``sigma_shift_e, sigma_shift_n,
        sigma_shift_h`` default to 0 (an empty ``sigma_shift_*`` cell too), ``source`` to
        ``"survey"`` (an empty cell too) and ``kind`` to ``kind``.
        (``source`` here is the file's name in messages; the column is ``columns["source"]``.)
        """
        missing = [c for c in ("id", "h") if c not in columns]
        n = len(np.asarray(columns["id"])) if "id" in columns else 0
        kinds = np.char.lower(np.char.strip(np.asarray(
            columns.get("kind", np.full(n, kind))).astype(str)))
        if not np.all(kinds == "hcp"):
            missing += [c for c in ("lon", "lat") if c not in columns]
        if missing:
            raise ObservationError(f"{source}: missing column(s) {missing}")
        nan = np.full(n, np.nan)
        # an empty sigma_shift cell is "no common error", as an absent column
        shift = {f"sigma_shift_{a}": np.nan_to_num(np.asarray(columns[f"sigma_shift_{a}"],
                                                              dtype=np.float64), nan=0.0)
                 if f"sigma_shift_{a}" in columns else 0.0 for a in "enh"}
        try:
            return cls(columns["id"], columns.get("kind", np.full(n, kind)),
                       columns.get("lon", nan), columns.get("lat", nan), columns["h"],
                       columns.get("sigma_e", 0.0), columns.get("sigma_n", 0.0),
                       columns.get("sigma_h", 0.0), columns.get("source", DEFAULT_SOURCE),
                       shift["sigma_shift_e"], shift["sigma_shift_n"], shift["sigma_shift_h"])
        except ObservationError as exc:
            raise ObservationError(str(exc).replace("ground points", source, 1)) from None

    def columns(self) -> dict[str, NDArray[Any]]:
        """The ground CSV's columns (:func:`geoblock.io.write_points`), every field in
        order: what :meth:`from_columns` reads back unchanged."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)}

    def subset(self, mask: ArrayLike) -> GroundPoints:
        """The points selected by a boolean mask or an index array."""
        m = np.asarray(mask)
        return GroundPoints(*(getattr(self, f.name)[m] for f in fields(self)))

    @property
    def shift_sigmas(self) -> Float64Array:
        """(N, 3) ``sigma_shift_e, sigma_shift_n, sigma_shift_h`` per point, metres."""
        return np.stack([self.sigma_shift_e, self.sigma_shift_n, self.sigma_shift_h], -1)


@dataclass(frozen=True, eq=False, init=False)
class ImagePoints:
    """Image measurements of a block, one row per measurement (the image CSV of a block).

    Parameters
    ----------
    id : array_like of str, (M,)
        Point identifier: a ground point's id (GCP, ICP) or a tie point's.
    image : array_like of str, (M,)
        Image id.
    row, col : array_like, (M,)
        Measured image coordinates, pixels (pixel-centre convention).
    sigma_row, sigma_col : array_like, (M,) or scalar
        Standard deviations, pixels (default 0.5 px, Teo et al.).
    kind : array_like of str, (M,), optional
        ``gcp``, ``icp``, ``tp``, ``ictp`` or ``hcp``; empty strings are resolved by
        :meth:`resolve_kinds` (a point with ground coordinates takes their kind, any other
        one is a TP).
    """

    id: StrArray
    image: StrArray
    row: Float64Array
    col: Float64Array
    sigma_row: Float64Array
    sigma_col: Float64Array
    kind: StrArray

    def __init__(
        self,
        id: ArrayLike,
        image: ArrayLike,
        row: ArrayLike,
        col: ArrayLike,
        sigma_row: ArrayLike = 0.5,
        sigma_col: ArrayLike = 0.5,
        kind: ArrayLike | None = None,
    ) -> None:
        where = "image measurements"
        ids = _text(id, None, "id", where)
        n = ids.shape[0]
        image_ = _text(image, n, "image", where)
        kind_ = (np.full(n, "", dtype="<U4") if kind is None
                 else np.char.lower(np.char.strip(_text(kind, n, "kind", where))))
        bad = ~np.isin(kind_, ("", *KINDS))
        if bad.any():
            raise ObservationError(f"{where}: kind must be one of {KINDS} (points "
                                   f"{_name_points(ids, bad)})")
        given = {"row": row, "col": col, "sigma_row": sigma_row, "sigma_col": sigma_col}
        values = {}
        for name, value in given.items():
            arr = _floats(value, n, name, where)
            bad = ~np.isfinite(arr) | (np.abs(arr) > 1e9)
            if name.startswith("sigma"):
                bad |= arr <= 0
            if bad.any():
                rule = "finite and > 0" if name.startswith("sigma") else "finite"
                raise ObservationError(f"{where}: {name} must be {rule} (points "
                                       f"{_name_points(ids, bad)})")
            arr.flags.writeable = False
            values[name] = arr
        key = np.char.add(np.char.add(ids, "\x00"), image_)
        unique, counts = np.unique(key, return_counts=True)
        if (counts > 1).any():
            dup = [k.replace("\x00", " in ") for k in unique[counts > 1][:5].tolist()]
            raise ObservationError(f"{where}: a point is measured twice in one image: {dup}")
        for name, text in (("id", ids), ("image", image_), ("kind", kind_)):
            text.flags.writeable = False
            object.__setattr__(self, name, text)
        for name, arr in values.items():
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return int(self.id.shape[0])

    @classmethod
    def from_columns(cls, columns: Mapping[str, ArrayLike], *, source: str = "image measurements",
                     sigma: float = 0.5) -> ImagePoints:
        """From the columns of an image CSV: ``id, image, row, col`` required; ``sigma``
        (both axes) or ``sigma_row, sigma_col`` default to ``sigma`` pixels; ``kind``
        optional."""
        missing = [c for c in ("id", "image", "row", "col") if c not in columns]
        if missing:
            raise ObservationError(f"{source}: missing column(s) {missing}")
        both = columns.get("sigma", sigma)
        try:
            return cls(columns["id"], columns["image"], columns["row"], columns["col"],
                       columns.get("sigma_row", both), columns.get("sigma_col", both),
                       columns.get("kind"))
        except ObservationError as exc:
            raise ObservationError(str(exc).replace("image measurements", source, 1)) from None

    def subset(self, mask: ArrayLike) -> ImagePoints:
        """The measurements selected by a boolean mask or an index array."""
        m = np.asarray(mask)
        return ImagePoints(self.id[m], self.image[m], self.row[m], self.col[m],
                           self.sigma_row[m], self.sigma_col[m], self.kind[m])

    def resolve_kinds(self, ground: GroundPoints | None) -> ImagePoints:
        """Kinds filled in and checked against the ground points.

        A measurement without a kind takes its ground point's kind, or ``tp`` when the point
        has no ground row. A measurement marked ``gcp``/``icp``/``hcp`` whose point is not in
        the ground file, or whose ground kind differs, is an error naming the point.
        """
        k = (np.full(len(self), -1, np.intp) if ground is None
             else lookup(ground.id, self.id))
        found = k >= 0
        ground_kind = np.where(found, ground.kind[np.maximum(k, 0)]
                               if ground is not None and len(ground) else "", "")
        kind = np.where(self.kind == "", np.where(found, ground_kind, "tp"), self.kind)
        bad = np.isin(kind, GROUND_KINDS) & ~found
        if bad.any():
            raise ObservationError(f"image measurements: points {_name_points(self.id, bad)} are "
                                   "marked gcp/icp/hcp but have no row in the ground points")
        bad = found & (kind != ground_kind) & np.isin(kind, GROUND_KINDS)
        if bad.any():
            raise ObservationError(f"image measurements: points {_name_points(self.id, bad)} "
                                   "have another kind than in the ground points")
        bad = found & np.isin(kind, ("tp", "ictp"))
        if bad.any():
            raise ObservationError(f"image measurements: points {_name_points(self.id, bad)} "
                                   "are marked tp/ictp but have ground coordinates")
        return ImagePoints(self.id, self.image, self.row, self.col, self.sigma_row,
                           self.sigma_col, kind)

    def control_points(self, ground: GroundPoints, image: str,
                       kinds: tuple[str, ...] = ("gcp",)) -> ControlPoints:
        """The one-image view: measurements of ``kinds`` in ``image`` joined with their
        ground coordinates, as :class:`ControlPoints` for :func:`geoblock.adjust.resect`."""
        meas = self.resolve_kinds(ground)
        sel = (meas.image == image) & np.isin(meas.kind, kinds)
        k = lookup(ground.id, meas.id[sel])
        return ControlPoints(meas.id[sel], ground.lon[k], ground.lat[k], ground.h[k],
                             meas.row[sel], meas.col[sel], meas.sigma_row[sel],
                             meas.sigma_col[sel], ground.sigma_e[k], ground.sigma_n[k],
                             ground.sigma_h[k])
