"""Terrain-dependent rational function models (RFM) fitted from GCPs alone.

Without vendor image support data an image can still be oriented by a ratio of polynomials in
normalised ground coordinates fitted to ground control points (GCPs): the *terrain-dependent*
RFM (Tao & Hu 2001; Aguilar et al. 2007, who found the first-order RFM-1 as accurate as the
physical model for QuickBird with about 18 well-spread GCPs). The model is an RPC00B whose
higher-order coefficients are zero, so everything that accepts an RPC (the orthorectifier, the
block adjustment, GDAL through the RPC writers) accepts it.

* Orders 1, 2, 3: 4, 10 or 20 terms per polynomial (RFM-1, RFM-2, RFM-3).
* Separate denominators (default: each image coordinate its own ratio, ``2 t - 1`` unknowns
  each, so at least 7 / 19 / 39 GCPs, Aguilar et al.) or one common denominator
  (``3 t - 1`` unknowns for ``2 n`` equations: at least 6 / 15 / 30 GCPs).
* Normalisation offsets and scales from the GCPs themselves (centre and half range).
* Linearised least squares weighted by the image sigmas, reweighted by ``1 / D``, with a
  Tikhonov term whose weight generalised cross-validation chooses
  (:func:`geoblock_rpc.rational.solve_ratios`).
* ``order="auto"``: the order with the lowest cross-validated image error (leave-one-out up to
  :data:`LOO_MAX_POINTS` GCPs, else :data:`K_FOLDS`-fold), reported per order.
* Diagnostics: condition number, regularisation weight, GCP residuals and, when check points
  are given, ICP residuals in pixels and on the ground (metres east/north, Aguilar et al.'s
  Table 3 figures).

Degenerate control is refused before any fitting, naming the cause: fewer GCPs than the
order needs (the minimum is stated), GCPs on one line or one plane (all at one height, for
example: a terrain-dependent RFM needs relief to determine its height terms), points measured
on one image line, and a design that the points do not determine.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np
import pyproj

from geoblock import ParameterSet, SensorModelBase, coords
from geoblock.errors import (
    CoordinateError,
    GeoblockWarning,
    ModelFormatError,
    SerializationError,
    SingularSystemError,
    TooFewPointsError,
)
from geoblock.models import image_shape
from geoblock.typing import ArrayLike, Status
from geoblock_rpc.rational import TERM_COUNTS, RatioFit, solve_ratios
from geoblock_rpc.rpc00b import Rpc00b, evaluate_terms, wrap_longitude

if TYPE_CHECKING:  # geoblock.adjust is imported when a fit runs, not when the plugin loads
    from geoblock.adjust import AccuracyStats, ControlPoints, PointResiduals

__all__ = ["K_FOLDS", "LOO_MAX_POINTS", "RfmFit", "RfmModel", "fit_rfm", "minimum_gcps"]

#: leave-one-out cross-validation up to this many GCPs, k-fold above
LOO_MAX_POINTS = 100
#: folds of the k-fold cross-validation (above :data:`LOO_MAX_POINTS` GCPs)
K_FOLDS = 10
#: relative singular value below which the GCPs' spread is degenerate (a line, a plane)
DEGENERATE = 1e-6
#: relative singular value below which the GCPs are nearly degenerate (a warning)
NEARLY_DEGENERATE = 1e-3


def minimum_gcps(order: int, common_denominator: bool = False) -> int:
    """The fewest GCPs that determine an RFM of ``order`` (denominator constant fixed to 1).

    Separate denominators: ``2 t - 1`` unknowns per image coordinate, one equation per GCP:
    7, 19, 39 for orders 1, 2, 3 (Aguilar et al. 2007). A common denominator: ``3 t - 1``
    unknowns for two equations per GCP: 6, 15, 30.
    """
    if order not in TERM_COUNTS:
        raise ValueError(f"RFM order must be 1, 2 or 3, got {order!r}")
    t = TERM_COUNTS[order]
    return math.ceil((3 * t - 1) / 2) if common_denominator else 2 * t - 1


@dataclass(frozen=True)
class RfmFit:
    """How an RFM was fitted, and how well it fits.

    Attributes
    ----------
    order : int
        1, 2 or 3.
    common_denominator : bool
    n_gcp : int
        GCPs fitted.
    condition : float
        Condition number of the column-scaled design (largest over the image coordinates).
    regularization : float
        Tikhonov weight chosen by generalised cross-validation (on the unit-norm columns).
    gcp : geoblock.adjust.PointResiduals
        GCP image residuals (observed - computed, pixels) and ground errors (the measured
        image point localised at the GCP's height minus the surveyed point, metres east/north).
    icp : geoblock.adjust.PointResiduals or None
        The same at independent check points, when given.
    cv_rms_px : dict of int to float
        Cross-validated 2D image RMS per order tried (``order="auto"``; empty otherwise).
    cv : str
        ``"leave-one-out"``, ``"10-fold"`` or ``""``.
    """

    order: int
    common_denominator: bool
    n_gcp: int
    condition: float
    regularization: float
    gcp: PointResiduals
    icp: PointResiduals | None = None
    cv_rms_px: dict[int, float] = field(default_factory=dict)
    cv: str = ""

    @property
    def gcp_ground(self) -> AccuracyStats:
        """GCP errors on the ground (``gcp.stats``), metres."""
        return self.gcp.stats

    @property
    def icp_ground(self) -> AccuracyStats | None:
        """ICP errors on the ground (``icp.stats``), metres; None without ICPs."""
        return None if self.icp is None else self.icp.stats

    def summary(self) -> str:
        """A few lines for people: order, control, conditioning and accuracy."""
        den = "common denominator" if self.common_denominator else "separate denominators"
        lines = [f"RFM-{self.order} ({den}) from {self.n_gcp} GCPs: condition "
                 f"{self.condition:.3g}, regularization {self.regularization:.3g}"]
        if self.cv_rms_px:
            lines.append(f"{self.cv} cross-validation, 2D image RMS: " + ", ".join(
                f"RFM-{k} {v:.3g} px" for k, v in sorted(self.cv_rms_px.items())))
        for label, px in (("GCP", self.gcp), ("ICP", self.icp)):
            if px is None:
                continue
            g = px.stats
            lines.append(f"{label} {g.n:3d}: image RMS {px.rms_px:.3g} px (max {px.max_px:.3g})"
                         f"; ground RMSE E {g.rmse_e:.3f} N {g.rmse_n:.3f} 2D {g.rmse_2d:.3f} m")
        return "\n".join(lines)


class RfmModel(SensorModelBase):
    """A terrain-dependent RFM fitted from GCPs: ratios of order-1, -2 or -3 polynomials.

    Built by :func:`fit_rfm`. The polynomials are RPC00B's (same terms, same order, each
    denominator's constant 1) in normalised ground coordinates of a *ground frame*: either
    geographic ``(lon, lat)`` degrees, which makes the model an RPC00B (:meth:`as_rpc`; GDAL
    and every RPC tool read it), or a projected CRS ``(E, N)`` metres, as photogrammetric
    packages fit terrain-dependent RFMs. Ground -> image is the closed form; image -> ground
    is the base class's Newton inversion.

    Parameters
    ----------
    order : {1, 2, 3}
    numerators, denominators : array_like, (2, 20)
        Row then column polynomials; coefficients beyond the order's terms must be zero and
        each denominator's constant 1.
    normalisation : mapping
        ``x_off, x_scale, y_off, y_scale, height_off, height_scale, line_off, line_scale,
        samp_off, samp_scale``: ground frame coordinates ``x, y`` (degrees, or metres of
        ``crs``), ``h`` metres above the ellipsoid, image pixels (pixel-centre convention).
    shape : (int, int)
        Image ``(rows, cols)``.
    crs : str, optional
        The projected ground frame (anything pyproj reads, in metres); None: geographic.
    common_denominator : bool
    fit : RfmFit, optional
        Diagnostics of the fit that made the model (not serialised).
    domain_limit, height_limit : float
        Points whose normalised ``|x|``, ``|y|`` exceed ``domain_limit`` or whose ``|H|``
        exceeds ``height_limit`` are OUT_OF_DOMAIN (NaN).
    """

    name: ClassVar[str] = "rfm"
    schema_version: ClassVar[int] = 1
    _NORMALISATION = ("x_off", "x_scale", "y_off", "y_scale", "height_off", "height_scale",
                      "line_off", "line_scale", "samp_off", "samp_scale")

    def __init__(self, order: int, numerators: ArrayLike, denominators: ArrayLike,
                 normalisation: Mapping[str, float], shape: tuple[int, int], *,
                 crs: str | None = None, common_denominator: bool = False,
                 fit: RfmFit | None = None, domain_limit: float = 1.5,
                 height_limit: float = 5.0) -> None:
        if order not in TERM_COUNTS:
            raise ModelFormatError(f"RFM order must be 1, 2 or 3, got {order!r}")
        t = TERM_COUNTS[order]
        num = np.array(numerators, dtype=float).reshape(2, 20)
        den = np.array(denominators, dtype=float).reshape(2, 20)
        if np.any(num[:, t:] != 0) or np.any(den[:, t:] != 0):
            raise ModelFormatError(f"an order-{order} RFM has no terms beyond the {t}th")
        if not (np.all(den[:, 0] == 1.0) and np.all(np.isfinite(num)) and
                np.all(np.isfinite(den))):
            raise ModelFormatError("RFM coefficients must be finite, denominator constants 1")
        missing = [k for k in self._NORMALISATION if k not in normalisation]
        if missing:
            raise ModelFormatError(f"RFM normalisation misses {missing}")
        self._norm = {k: float(normalisation[k]) for k in self._NORMALISATION}
        if not all(math.isfinite(v) for v in self._norm.values()) or min(
                abs(self._norm[k]) for k in self._NORMALISATION if k.endswith("scale")) <= 0:
            raise ModelFormatError(f"RFM normalisation must be finite, scales non-zero: "
                                   f"{self._norm}")
        self._crs = None if crs is None else pyproj.CRS.from_user_input(crs)
        if self._crs is not None and not self._crs.is_projected:
            raise ModelFormatError(f"RFM ground frame {crs!r} is not a projected CRS; use "
                                   "None for geographic (lon, lat)")
        self._order, self._common = int(order), bool(common_denominator)
        self._num, self._den = num, den
        self._shape = image_shape(shape, "RFM")
        self._fit = fit
        self._domain_limit, self._height_limit = float(domain_limit), float(height_limit)
        n = self._norm
        self._height_range = (n["height_off"] - abs(n["height_scale"]),
                              n["height_off"] + abs(n["height_scale"]))

    @classmethod
    def example(cls) -> Self:
        """An RFM-1 fitted (UTM frame) to 40 error-free GCPs of the synthetic pushbroom
        (``geoblock.testing.synthetic.ConstantVelocityPushbroom.example()``)."""
        from geoblock.adjust import ControlPoints
        from geoblock.testing.synthetic import ConstantVelocityPushbroom

        truth = ConstantVelocityPushbroom.example()
        rng = np.random.default_rng(15)
        rows, cols = truth.shape
        row, col = rng.uniform(-0.5, rows - 0.5, 40), rng.uniform(-0.5, cols - 0.5, 40)
        h = rng.uniform(*truth.height_range, 40)
        g = truth.backproject(row, col, h)
        gcps = ControlPoints([f"G{i}" for i in range(40)], g.lon, g.lat, h, row, col)
        return fit_rfm(gcps, order=1, shape=truth.shape)  # type: ignore[return-value]

    # ------------------------------------------------------------------ state
    @property
    def order(self) -> int:
        """Polynomial order (1: RFM-1, 4 terms per polynomial; 2: 10; 3: 20)."""
        return self._order

    @property
    def common_denominator(self) -> bool:
        """Whether the row and column ratios share one denominator."""
        return self._common

    @property
    def crs(self) -> str | None:
        """The projected ground frame (``"EPSG:32630"``...), None for geographic."""
        return None if self._crs is None else _crs_text(self._crs)

    @property
    def fit(self) -> RfmFit | None:
        """Diagnostics of the fit (None for a model read from JSON)."""
        return self._fit

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def height_range(self) -> tuple[float, float]:
        """The GCPs' height range (``HEIGHT_OFF -/+ HEIGHT_SCALE``), metres above the ellipsoid."""
        return self._height_range

    @property
    def domain_limit(self) -> float:
        """Horizontal validity limit on the normalised ground coordinates."""
        return self._domain_limit

    @property
    def parameters(self) -> ParameterSet:
        return ParameterSet.empty()

    def with_parameters(self, values: ArrayLike) -> Self:
        self.parameters.with_values(values)  # refuses anything but an empty array
        return self

    def as_rpc(self) -> Rpc00b | None:
        """The exact RPC00B of a geographic-frame RFM (None for a projected frame)."""
        if self._crs is not None:
            return None
        n = self._norm
        return Rpc00b(
            line_off=n["line_off"], samp_off=n["samp_off"], lat_off=n["y_off"],
            long_off=n["x_off"], height_off=n["height_off"], line_scale=n["line_scale"],
            samp_scale=n["samp_scale"], lat_scale=n["y_scale"], long_scale=n["x_scale"],
            height_scale=n["height_scale"], line_num=self._num[0], line_den=self._den[0],
            samp_num=self._num[1], samp_den=self._den[1], source=f"RFM-{self._order}",
        )

    def to_dict(self) -> dict[str, Any]:
        t = TERM_COUNTS[self._order]
        return {
            "model": self.name, "schema_version": self.schema_version,
            "shape": list(self._shape), "order": self._order,
            "common_denominator": self._common, "crs": self.crs,
            "normalisation": dict(self._norm),
            "numerators": self._num[:, :t].tolist(),
            "denominators": self._den[:, :t].tolist(),
            "domain_limit": self._domain_limit, "height_limit": self._height_limit,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        try:
            order = int(data["order"])
            t = TERM_COUNTS[order]
            num = np.zeros((2, 20))
            den = np.zeros((2, 20))
            num[:, :t] = np.asarray(data["numerators"], dtype=float).reshape(2, t)
            den[:, :t] = np.asarray(data["denominators"], dtype=float).reshape(2, t)
            return cls(order, num, den, data["normalisation"], tuple(data["shape"]),
                       crs=data.get("crs"),
                       common_denominator=bool(data.get("common_denominator", False)),
                       domain_limit=data.get("domain_limit", 1.5),
                       height_limit=data.get("height_limit", 5.0))
        except KeyError as exc:
            raise SerializationError(f"rfm model dictionary misses {exc}") from None
        except (ModelFormatError, TypeError, ValueError, pyproj.exceptions.CRSError) as exc:
            raise SerializationError(f"rfm model dictionary: {exc}") from exc

    # ------------------------------------------------------------------ directions
    def _frame_xy(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised ground-frame coordinates of (lon, lat) degrees."""
        return _normalised_xy(self._crs, self._norm, lon, lat)

    def ground_to_image(self, lon, lat, h):
        """Closed form: ``off + scale * N(T) / D(T)`` per image coordinate."""
        n = self._norm
        x, y = self._frame_xy(lon, lat)
        z = (h - n["height_off"]) / n["height_scale"]
        t = TERM_COUNTS[self._order]
        terms = evaluate_terms(x, y, z)[:, :t]
        den = terms @ self._den[:, :t].T
        ratio = (terms @ self._num[:, :t].T) / den
        ok = ((np.abs(x) <= self._domain_limit) & (np.abs(y) <= self._domain_limit)
              & (np.abs(z) <= self._height_limit) & np.all(den > 0, axis=1)
              & np.all(np.isfinite(ratio), axis=1))
        row = np.where(ok, ratio[:, 0] * n["line_scale"] + n["line_off"], np.nan)
        col = np.where(ok, ratio[:, 1] * n["samp_scale"] + n["samp_off"], np.nan)
        status = np.where(ok, Status.CONVERGED, Status.OUT_OF_DOMAIN).astype(np.uint8)
        return row, col, status

    def ground_seed(self) -> tuple[float, float]:
        n = self._norm
        if self._crs is None:
            return n["x_off"], n["y_off"]
        lon, lat = coords.transformer(self._crs, 4326).transform(n["x_off"], n["y_off"])
        return float(lon), float(lat)

    def __repr__(self) -> str:
        frame = self.crs or "lon/lat"
        return (f"<RfmModel RFM-{self._order} in {frame}, {self._shape[0]}x{self._shape[1]} px, "
                f"h {self._height_range[0]:g}..{self._height_range[1]:g} m>")


def _crs_text(crs: pyproj.CRS) -> str:
    """``"EPSG:32630"`` when the CRS has an EPSG code, else its WKT."""
    code = crs.to_epsg()
    return f"EPSG:{code}" if code is not None else crs.to_wkt()


# ---------------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class _Normalisation:
    """Offsets and scales from the points (centre and half range) in a ground frame."""

    crs: pyproj.CRS | None
    values: dict[str, float]

    @classmethod
    def of(cls, p: ControlPoints, crs: pyproj.CRS | None) -> _Normalisation:
        def centre_half(v: np.ndarray, least: float) -> tuple[float, float]:
            lo, hi = float(v.min()), float(v.max())
            return 0.5 * (lo + hi), max(0.5 * (hi - lo), least)

        if crs is None:
            lon0 = float(np.median(p.lon))
            x_c, x_s = centre_half(wrap_longitude(p.lon - lon0), 1e-7)
            x_c += lon0
            y_c, y_s = centre_half(p.lat, 1e-7)
        else:
            x, y = coords.transformer(4326, crs).transform(p.lon, p.lat)
            (x_c, x_s), (y_c, y_s) = centre_half(np.asarray(x), 1e-2), centre_half(
                np.asarray(y), 1e-2)
        h_c, h_s = centre_half(p.h, 1.0)
        r_c, r_s = centre_half(p.row, 0.5)
        c_c, c_s = centre_half(p.col, 0.5)
        return cls(crs, dict(zip(RfmModel._NORMALISATION,
                                 (x_c, x_s, y_c, y_s, h_c, h_s, r_c, r_s, c_c, c_s), strict=True)))

    def xyz(self, p: ControlPoints) -> np.ndarray:
        """Normalised ground-frame coordinates (n, 3) of the points."""
        v = self.values
        x, y = _normalised_xy(self.crs, v, p.lon, p.lat)
        return np.stack([x, y, (p.h - v["height_off"]) / v["height_scale"]], axis=1)

    def image(self, p: ControlPoints) -> np.ndarray:
        v = self.values
        return np.stack([(p.row - v["line_off"]) / v["line_scale"],
                         (p.col - v["samp_off"]) / v["samp_scale"]], axis=1)


def _normalised_xy(crs: pyproj.CRS | None, norm: Mapping[str, float], lon: np.ndarray,
                   lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised ground-frame ``x, y`` of (lon, lat) degrees: longitude differences wrapped
    to +/-180 in lon/lat, else easting/northing in the projected ``crs``."""
    if crs is None:
        x, y = wrap_longitude(lon - norm["x_off"]), lat - norm["y_off"]
    else:
        e, n = coords.transformer(4326, crs).transform(lon, lat)
        x, y = np.asarray(e) - norm["x_off"], np.asarray(n) - norm["y_off"]
    return x / norm["x_scale"], y / norm["y_scale"]


def _spread(points: np.ndarray) -> np.ndarray:
    """Singular values of the centred points (n, d), relative to the largest."""
    centred = points - points.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    return s / s[0] if s[0] > 0 else np.zeros_like(s)


def _check_count(gcps: ControlPoints, order: int, common: bool) -> None:
    """Refuse fewer distinct GCPs than an order-``order`` RFM needs, stating the minimum."""
    n = len(gcps.id)
    need = minimum_gcps(order, common)
    den = "a common denominator" if common else "separate denominators"
    key = np.stack([gcps.lon, gcps.lat, gcps.h], axis=1)
    distinct = len(np.unique(key, axis=0))
    if distinct < need:
        repeated = "" if distinct == n else f" ({n} given, {n - distinct} repeating another's " \
                                             "ground position)"
        raise TooFewPointsError(
            f"an order-{order} RFM ({den}) needs at least {need} GCPs, got {distinct} "
            f"distinct ones{repeated}; use a lower order (RFM-1 needs 7) or more GCPs"
        )


def _check_spread(gcps: ControlPoints) -> None:
    """Refuse GCPs on a line or a plane (in metres), warn when nearly coplanar."""
    n = len(gcps.id)
    # judged in metres (local east, north, up), where "flat" has a meaning
    lon0, lat0 = float(np.median(gcps.lon)), float(np.median(gcps.lat))
    e, nn, u = coords.enu_offsets(np.full(n, lon0), np.full(n, lat0), np.zeros(n), gcps.lon,
                                  gcps.lat, gcps.h)
    if _spread(np.stack([e, nn], axis=1))[-1] < DEGENERATE:
        raise SingularSystemError(
            f"the {n} GCPs are collinear on the ground (they lie on one line in plan): an RFM "
            "needs GCPs spread over the image"
        )
    if _spread(np.stack([gcps.row, gcps.col], axis=1))[-1] < DEGENERATE:
        raise SingularSystemError(
            f"the {n} GCPs are collinear in the image (measured on one line): an RFM needs "
            "GCPs spread over the image"
        )
    width = float(np.sqrt(np.ptp(e) ** 2 + np.ptp(nn) ** 2))
    space = _spread(np.stack([e, nn, u], axis=1))
    flat = float(np.ptp(gcps.h)) <= DEGENERATE * width
    if flat or space[-1] < DEGENERATE:
        cause = f"all at one height ({float(np.median(gcps.h)):g} m)" if flat else \
            "on one tilted plane"
        raise SingularSystemError(
            f"the {n} GCPs are coplanar ({cause}): a terrain-dependent RFM cannot determine its "
            "height terms without relief; add GCPs at other heights, or refine a vendor RPC "
            "(geoblock refine, RPCV-0/1) instead"
        )
    space = np.minimum(space, np.ptp(gcps.h) / max(width, 1e-300))
    if space[-1] < NEARLY_DEGENERATE:
        warnings.warn(
            f"the {n} GCPs are nearly coplanar (they are within {space[-1]:.2g} of their "
            "horizontal spread off one plane): the RFM's height terms are poorly determined "
            "away from the GCPs' surface", GeoblockWarning, stacklevel=3,
        )


# ---------------------------------------------------------------------------------- fitting
def _ratio(gcps: ControlPoints, norm: _Normalisation, order: int, common: bool,
           regularization: float | str) -> RatioFit:
    terms = evaluate_terms(*norm.xyz(gcps).T)
    v = norm.values
    weights = np.stack([v["line_scale"] / gcps.sigma_row, v["samp_scale"] / gcps.sigma_col], 1)
    # guard the whole box spanned by the GCPs (and a margin) against poles
    g = np.linspace(-1.1, 1.1, 9)
    gx, gy, gh = np.meshgrid(g, g, np.linspace(-1.0, 1.0, 3), indexing="ij")
    guard = evaluate_terms(gx.ravel(), gy.ravel(), gh.ravel())
    return solve_ratios(terms, norm.image(gcps), order=order, common=common, weights=weights,
                        regularization=regularization, guard=guard)


def _model(ratio: RatioFit, norm: _Normalisation, order: int, common: bool,
           shape: tuple[int, int] | None, **kwargs: Any) -> RfmModel:
    v = norm.values
    if shape is None:
        shape = (max(1, math.ceil(v["line_off"] + v["line_scale"] + 0.5)),
                 max(1, math.ceil(v["samp_off"] + v["samp_scale"] + 0.5)))
    return RfmModel(order, ratio.numerators, ratio.denominators, v, shape,
                    crs=None if norm.crs is None else _crs_text(norm.crs),
                    common_denominator=common, **kwargs)


def _folds(n: int) -> tuple[str, list[np.ndarray]]:
    if n <= LOO_MAX_POINTS:
        return "leave-one-out", [np.array([i]) for i in range(n)]
    order = np.random.default_rng(0).permutation(n)
    return f"{K_FOLDS}-fold", [np.sort(f) for f in np.array_split(order, K_FOLDS)]


def _cv_rms(gcps: ControlPoints, order: int, common: bool, crs: pyproj.CRS | None,
            regularization: float | str) -> tuple[str, float]:
    """Cross-validated 2D image RMS (pixels) of an order-``order`` RFM on ``gcps``."""
    n = len(gcps.id)
    how, folds = _folds(n)
    errors = np.full((n, 2), np.nan)
    for held in folds:
        keep = np.ones(n, bool)
        keep[held] = False
        train = gcps.subset(keep)
        norm = _Normalisation.of(train, crs)
        try:
            model = _model(_ratio(train, norm, order, common, regularization), norm, order,
                           common, None, domain_limit=1e3, height_limit=1e3)
        except (SingularSystemError, ModelFormatError):
            return how, math.inf
        test = gcps.subset(~keep)
        row, col = model.project(test.lon, test.lat, test.h)
        errors[held] = np.stack([np.asarray(row) - test.row, np.asarray(col) - test.col], 1)
    if not np.all(np.isfinite(errors)):
        return how, math.inf
    return how, float(np.sqrt(np.mean(np.sum(errors**2, axis=1))))


def fit_rfm(
    gcps: ControlPoints,
    *,
    order: int | str = 1,
    common_denominator: bool = False,
    crs: str | int | None = "utm",
    shape: tuple[int, int] | None = None,
    icps: ControlPoints | None = None,
    regularization: float | str = "gcv",
) -> RfmModel:
    """Fit a terrain-dependent RFM (RFM-1, -2 or -3) to ground control points.

    Parameters
    ----------
    gcps : geoblock.adjust.ControlPoints
        Ground (``lon, lat`` degrees, ``h`` metres above the ellipsoid) and measured image
        coordinates (``row, col`` pixels, pixel-centre convention) with their sigmas
        (``sigma_row, sigma_col`` pixels weight the fit).
    order : {1, 2, 3} or "auto"
        Polynomial order; ``"auto"`` fits every order the GCPs allow (a cross-validation needs
        one more than the minimum) and keeps the one with the lowest cross-validated image
        RMS (:attr:`RfmFit.cv_rms_px`).
    common_denominator : bool
        One denominator for rows and columns (fewer unknowns) instead of one each (default,
        as in Aguilar et al.).
    crs : "utm", "geographic" or a projected CRS
        The ground frame of the polynomials. ``"utm"`` (default): the WGS84 UTM zone of the
        GCPs, as photogrammetric packages fit terrain-dependent RFMs in map coordinates; in
        geographic coordinates a parallel is curved (``tan(lat) d^2 / 8R``: 4 m over 17 km at
        37 deg N), which a first-order RFM cannot follow. ``"geographic"`` (or None) fits
        in ``(lon, lat)``: the model is then an exact RPC00B (:meth:`RfmModel.as_rpc`).
    shape : (int, int), optional
        Image ``(rows, cols)``; default the extent of the GCPs' image coordinates.
    icps : ControlPoints, optional
        Independent check points: not fitted, their residuals are reported in
        :attr:`RfmModel.fit`.
    regularization : float or "gcv"
        Tikhonov weight on the unit-norm columns, or ``"gcv"`` to choose it by generalised
        cross-validation (:func:`geoblock_rpc.rational.solve_ratios`).

    Returns
    -------
    RfmModel
        With the fit diagnostics in :attr:`RfmModel.fit`.

    Raises
    ------
    TooFewPointsError
        Fewer distinct GCPs than the order needs (:func:`minimum_gcps`; the message states it).
    SingularSystemError
        GCPs collinear (on the ground or in the image) or coplanar (all at one height), or a
        fit whose denominator cannot be kept away from zero.

    Examples
    --------
    >>> import numpy as np
    >>> from geoblock.adjust import ControlPoints
    >>> from geoblock.testing.synthetic import ConstantVelocityPushbroom
    >>> truth = ConstantVelocityPushbroom.example()
    >>> rng = np.random.default_rng(1)
    >>> row, col = rng.uniform(0, 800, 20), rng.uniform(0, 1000, 20)
    >>> h = rng.uniform(0, 1500, 20)
    >>> lon, lat, _ = truth.backproject(row, col, h)
    >>> rfm = fit_rfm(ControlPoints(np.arange(20).astype(str), lon, lat, h, row, col),
    ...               order=1, shape=truth.shape)
    >>> rfm.order, rfm.fit.gcp.rms_px < 0.1
    (1, True)
    """
    from geoblock.adjust import ControlPoints, PointResiduals

    if not isinstance(gcps, ControlPoints):
        raise TypeError(f"fit_rfm needs geoblock.adjust.ControlPoints, got {type(gcps).__name__}")
    frame = _frame(crs, gcps)
    cv: dict[int, float] = {}
    how = ""
    if order == "auto":
        n = len(gcps.id)
        candidates = [k for k in (1, 2, 3) if n > minimum_gcps(k, common_denominator)]
        if not candidates:
            raise TooFewPointsError(
                f"order='auto' cross-validates, so it needs at least "
                f"{minimum_gcps(1, common_denominator) + 1} GCPs (one more than RFM-1's "
                f"minimum), got {n}"
            )
        _check_spread(gcps)
        for k in candidates:
            how, cv[k] = _cv_rms(gcps, k, common_denominator, frame, regularization)
        finite = {k: v for k, v in cv.items() if math.isfinite(v)}
        if not finite:
            raise SingularSystemError("no RFM order could be fitted in every cross-validation "
                                      "fold: the GCPs do not determine a rational function")
        order = min(finite, key=finite.__getitem__)
    if order not in TERM_COUNTS:
        raise ValueError(f"order must be 1, 2, 3 or 'auto', got {order!r}")
    k_order = int(order)
    norm = _Normalisation.of(gcps, frame)
    _check_count(gcps, k_order, common_denominator)
    if not cv:  # order="auto" checked the spread already
        _check_spread(gcps)
    ratio = _ratio(gcps, norm, k_order, common_denominator, regularization)
    probe = _model(ratio, norm, k_order, common_denominator, shape, domain_limit=1e3,
                   height_limit=1e3)
    # the validity domain must hold the whole image, not only the GCPs' hull
    rows, cols = probe.shape
    corner_r = np.array([-0.5, -0.5, rows - 0.5, rows - 0.5, (rows - 1) / 2])
    corner_c = np.array([-0.5, cols - 0.5, -0.5, cols - 0.5, (cols - 1) / 2])
    lon, lat, _ = probe.backproject(corner_r, corner_c,
                                    np.full(5, norm.values["height_off"]))
    x, y = probe._frame_xy(lon, lat)
    reach = np.nanmax(np.abs(np.concatenate([x, y]))) if np.isfinite(x).any() else np.nan
    domain = max(1.5, 1.2 * float(reach)) if np.isfinite(reach) else 1.5
    # diagnostics through the probe: its wider domain reports ICPs beyond the image too
    gcp_px = PointResiduals.of(probe, gcps)
    icp_px = PointResiduals.of(probe, icps) if icps is not None and len(icps.id) else None
    diagnostics = RfmFit(
        order=k_order, common_denominator=common_denominator, n_gcp=len(gcps.id),
        condition=ratio.condition, regularization=ratio.regularization, gcp=gcp_px,
        icp=icp_px, cv_rms_px=cv, cv=how,
    )
    return _model(ratio, norm, k_order, common_denominator, probe.shape, domain_limit=domain,
                  fit=diagnostics)


def _frame(crs: str | int | None, gcps: ControlPoints) -> pyproj.CRS | None:
    """The ground frame: None (geographic) or a projected CRS in metres."""
    if crs is None or (isinstance(crs, str) and crs.lower() == "geographic"):
        return None
    if isinstance(crs, str) and crs.lower() == "utm":
        return coords.utm_crs(gcps.lon, gcps.lat)
    try:
        frame = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as exc:
        raise CoordinateError(f"RFM ground frame {crs!r} is not a CRS pyproj knows: "
                              f"{exc}") from None
    if not frame.is_projected or frame.axis_info[0].unit_name not in ("metre", "meter"):
        raise CoordinateError(f"RFM ground frame {crs!r} must be a projected CRS in metres "
                              "(or 'utm', or 'geographic')")
    return frame
