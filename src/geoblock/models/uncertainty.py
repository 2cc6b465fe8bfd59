"""How well a sensor model locates the ground: a parameter covariance propagated to the ground.

A sensor model's parameters carry an uncertainty, either stated before any adjustment (the
a-priori sigmas of its :class:`~geoblock.models.ParameterSet`, or the location accuracy a
product states, e.g. an RPC's ``ERR_BIAS``) or estimated by one (the posterior covariance of
a block adjustment, :class:`ModelPosterior`, carried in the adjusted model's JSON). This module
turns either into the covariance of the horizontal ground error of image points, generically
through the :class:`~geoblock.models.SensorModel` protocol's partials:

* **model part**: at a fixed image point and height, a parameter error ``dp`` moves the ground
  point by ``-J_g^-1 J_p dp``, with ``J_g`` the (2, 2) partial of ``(row, col)`` with respect to
  local ``(east, north)`` and ``J_p`` the (2, K) partials with respect to the parameters; its
  covariance is ``G C G^T`` with ``G = J_g^-1 J_p``;
* **DEM part**: a height error ``dh`` moves the ground point seen at a fixed image point by
  ``-J_g^-1 J_h dh`` (``J_h`` the partial with respect to the local up), a horizontal
  displacement of ``tan(incidence)`` metres per metre of height for a frame or pushbroom view;
  its covariance is ``sigma_DEM^2 v v^T`` with ``v = J_g^-1 J_h`` (Aguilar et al. 2007's budget
  ``sigma_ortho^2 = sigma_o^2 + (sigma_DEM tan(theta))^2``);
* a stated **location accuracy** ``s`` (1 sigma per horizontal axis, metres) without
  parameters adds ``s^2 I``.

The scalar a per-pixel accuracy layer holds is the **radial RMS** ``sqrt(trace(C))`` (metres):
the root of the expected squared horizontal error, which an RMSE_r measured at check points
estimates. The circular error at 90 % of one point lies between 1.5175 (circular error
ellipse) and 1.6449 (a line) times it; :func:`geoblock.adjust.accuracy.predicted_ce` gives it
exactly from the covariances.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock import coords
from geoblock._array import broadcast_float64
from geoblock.errors import GeoblockError, GeoblockWarning, SerializationError
from geoblock.typing import ArrayLike, Float64Array

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel

__all__ = ["AccuracyWarning", "GroundError", "ModelAccuracy", "ModelPosterior",
           "NoAccuracyError", "ground_error", "model_accuracy"]


class NoAccuracyError(GeoblockError, ValueError):
    """A sensor model states no accuracy: no posterior covariance, every a-priori sigma
    infinite and no stated location accuracy; or a posterior that is not the model's."""


class AccuracyWarning(GeoblockWarning):
    """An accuracy statement leaves something out (adjustable parameters with an infinite
    a-priori sigma: they are not in the propagated covariance)."""


# ------------------------------------------------------------------ the posterior
@dataclass(frozen=True, eq=False)
class ModelPosterior:
    """The posterior covariance of a model's adjusted parameters, as a block adjustment
    estimated it; :func:`geoblock.io.write_model` stores it in the model JSON (key
    ``"posterior"``) and :func:`geoblock.io.read_model_posterior` reads it back.

    Parameters
    ----------
    names : sequence of str, (K,)
        The adjusted parameters (a subset of the model's ``parameters.names``), unique.
    covariance : array_like, (K, K)
        Their posterior covariance, in their units squared (already scaled by the
        adjustment's variance of unit weight), symmetric, finite, non-negative diagonal.
    sigma0 : float, optional
        The adjustment's posterior standard deviation of unit weight.
    dof : int, optional
        Its degrees of freedom.
    source : str
        What produced it (``"geoblock adjust block.toml"``).
    """

    names: tuple[str, ...]
    covariance: Float64Array
    sigma0: float | None = None
    dof: int | None = None
    source: str = ""

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        if len(set(names)) != len(names):
            raise SerializationError(f"ModelPosterior: duplicate parameter names {names}")
        cov = np.array(self.covariance, dtype=np.float64)
        k = len(names)
        if cov.shape != (k, k):
            raise SerializationError(
                f"ModelPosterior: {k} names but a covariance of shape {cov.shape}")
        if not np.all(np.isfinite(cov)):
            raise SerializationError("ModelPosterior: the covariance is not finite")
        if not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
            raise SerializationError("ModelPosterior: the covariance is not symmetric")
        if np.any(np.diag(cov) < 0):
            raise SerializationError("ModelPosterior: the covariance has a negative variance")
        cov.flags.writeable = False
        sigma0 = None if self.sigma0 is None else float(self.sigma0)
        dof = None if self.dof is None else int(self.dof)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "sigma0", sigma0)
        object.__setattr__(self, "dof", dof)
        object.__setattr__(self, "source", str(self.source))

    @property
    def sigmas(self) -> Float64Array:
        """(K,) posterior standard deviations, in the parameters' units."""
        return np.sqrt(np.diag(self.covariance))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: ``names``, ``covariance`` (list of rows), ``sigma0``, ``dof``,
        ``source`` (``sigma0`` null when not finite)."""
        sigma0 = self.sigma0 if self.sigma0 is not None and math.isfinite(self.sigma0) else None
        return {"names": list(self.names),
                "covariance": [[float(v) for v in row] for row in self.covariance],
                "sigma0": sigma0, "dof": self.dof, "source": self.source}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ModelPosterior:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        SerializationError
            A missing or malformed field (names the field).
        """
        if not isinstance(data, Mapping):
            raise SerializationError(f"posterior must be an object, got {type(data).__name__}")
        try:
            names = data["names"]
            cov = data["covariance"]
        except KeyError as exc:
            raise SerializationError(f"posterior lacks {exc}") from None
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise SerializationError(f"posterior.names must be a list of strings, got {names!r}")
        try:
            matrix = np.array(cov, dtype=np.float64).reshape(len(names), len(names))
        except (TypeError, ValueError) as exc:
            raise SerializationError(
                f"posterior.covariance must be {len(names)} rows of {len(names)} numbers: "
                f"{exc}") from None
        sigma0 = data.get("sigma0")
        dof = data.get("dof")
        if sigma0 is not None and not isinstance(sigma0, int | float):
            raise SerializationError(f"posterior.sigma0 must be a number, got {sigma0!r}")
        if dof is not None and not (isinstance(dof, int) and not isinstance(dof, bool)):
            raise SerializationError(f"posterior.dof must be an integer, got {dof!r}")
        return cls(tuple(names), matrix, sigma0, dof, str(data.get("source", "")))

    @classmethod
    def from_block_result(cls, result: Any, image: str,
                          source: str = "geoblock adjust") -> ModelPosterior | None:
        """The posterior of one image of a :class:`~geoblock.adjust.BlockResult`, or None.

        None when the image's adjusted parameters are not parameters of its model in the
        result (a model wrapped in a least-squares collocation has none: the covariance is of
        the wrapped model's parameters) or when it had no adjusted parameter.

        Parameters
        ----------
        result : BlockResult
            Uses ``models``, ``parameter_covariance(image)``, ``sigma0`` and ``dof``.
        image : str
        source : str
            Stored as :attr:`source`.
        """
        names, cov = result.parameter_covariance(image)
        model = result.models[image]
        if not names or not set(names) <= set(model.parameters.names):
            return None
        return cls(tuple(names), cov, float(result.sigma0), int(result.dof), source)


# ------------------------------------------------------------------ the statement used
@dataclass(frozen=True, eq=False)
class ModelAccuracy:
    """The accuracy statement of a model that :func:`ground_error` propagates.

    Attributes
    ----------
    names : tuple of str, (K,)
        Parameters whose covariance is propagated (may be empty).
    covariance : ndarray, (K, K)
        Their covariance, units squared.
    location_sigma_m : float
        A stated location accuracy, 1 sigma per horizontal axis, metres, added as
        ``s^2 I`` (0 when the statement is a parameter covariance).
    kind : str
        ``"posterior"`` (a block adjustment's) or ``"a-priori"``.
    source : str
        In words, for the layer's tags: the adjustment, or which a-priori statement.
    """

    names: tuple[str, ...]
    covariance: Float64Array
    location_sigma_m: float = 0.0
    kind: str = "a-priori"
    source: str = ""
    left_out: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe state (for tokens and pickling)."""
        return {"names": list(self.names), "covariance": self.covariance.tolist(),
                "location_sigma_m": self.location_sigma_m, "kind": self.kind,
                "source": self.source, "left_out": list(self.left_out)}

    def __dask_tokenize__(self) -> tuple[str, str]:
        import json

        return ("ModelAccuracy", json.dumps(self.to_dict(), sort_keys=True))


def _stated_location_accuracy(model: SensorModel) -> float | None:
    """``location_accuracy_m`` of the model or of a model it wraps (``.model``)."""
    seen = 0
    m: Any = model
    while m is not None and seen < 8:
        value = getattr(m, "location_accuracy_m", None)
        if isinstance(value, int | float) and not isinstance(value, bool) \
                and math.isfinite(value) and value > 0:
            return float(value)
        inner = getattr(m, "model", None)
        m = inner if inner is not m else None
        seen += 1
    return None


def model_accuracy(model: SensorModel, posterior: ModelPosterior | None = None,
                   *, where: str = "") -> ModelAccuracy:
    """The accuracy statement of ``model``: its posterior, else what it states a priori.

    In order:

    1. ``posterior`` (a block adjustment's, :func:`geoblock.io.read_model_posterior`):
       its names must be parameters of ``model``;
    2. the a-priori covariance of the parameters whose a-priori sigma is finite
       (``model.parameters.prior_covariance``; a linescan preset's sigmas, an information
       prior's marginal covariance). Adjustable parameters with an infinite sigma state
       nothing about themselves: they are left out with an :class:`AccuracyWarning`;
    3. the location accuracy the product states (``location_accuracy_m`` of the model or of
       a model it wraps, e.g. an RPC's ``ERR_BIAS``), 1 sigma per horizontal axis.

    Parameters
    ----------
    model : SensorModel
    posterior : ModelPosterior, optional
    where : str
        What the model is (a file name), for the messages.

    Returns
    -------
    ModelAccuracy

    Raises
    ------
    NoAccuracyError
        None of the three: the model states no accuracy (adjust it with ``geoblock adjust``,
        whose models carry their posterior, or give the product's accuracy); or a posterior
        naming parameters the model does not have.
    """
    label = f"{where}: " if where else ""
    params = model.parameters
    if posterior is not None:
        missing = [n for n in posterior.names if n not in params.names]
        if missing:
            raise NoAccuracyError(
                f"{label}the posterior covariance names parameters the model "
                f"{model.name!r} does not have: {missing} (its parameters: "
                f"{list(params.names)}); it belongs to another model")
        source = posterior.source or "block adjustment"
        if posterior.sigma0 is not None and math.isfinite(posterior.sigma0):
            source += f" (sigma0 {posterior.sigma0:.4g}, dof {posterior.dof})"
        return ModelAccuracy(posterior.names, np.array(posterior.covariance), 0.0,
                             "posterior", source)
    if len(params):
        prior = np.asarray(params.prior_covariance, dtype=np.float64)
        diag = np.diag(prior)
        finite = np.isfinite(diag)
        free = [n for n, f, a in zip(params.names, finite, params.adjustable, strict=True)
                if not f and a]
        if finite.any():
            idx = np.flatnonzero(finite)
            names = tuple(params.names[i] for i in idx)
            if free:
                warnings.warn(
                    f"{label}model {model.name!r}: the adjustable parameters {free} have no "
                    "a-priori sigma (infinite): the accuracy statement leaves them out",
                    AccuracyWarning, stacklevel=2)
            return ModelAccuracy(names, prior[np.ix_(idx, idx)], 0.0, "a-priori",
                                 f"a-priori sigmas of {len(names)} parameters of model "
                                 f"{model.name!r}", tuple(free))
    stated = _stated_location_accuracy(model)
    if stated is not None:
        return ModelAccuracy((), np.zeros((0, 0)), stated, "a-priori",
                             f"stated location accuracy of model {model.name!r}: {stated:g} m "
                             "(1 sigma per axis)")
    raise NoAccuracyError(
        f"{label}model {model.name!r} states no accuracy: no posterior covariance, no finite "
        "a-priori parameter sigma and no stated location accuracy. Adjust it (geoblock "
        "adjust writes models/<image>.json with its posterior covariance) and use that model")


# ------------------------------------------------------------------ propagation
@dataclass(frozen=True, eq=False)
class GroundError:
    """Predicted horizontal ground error at points (:func:`ground_error`).

    Attributes
    ----------
    lon, lat, h : ndarray, (N,)
        The ground points (degrees, metres above the ellipsoid).
    model : ndarray, (N, 2, 2)
        East/north covariance of the model part, square metres.
    dem : ndarray, (N, 2, 2)
        East/north covariance of the DEM part, square metres.
    displacement : ndarray, (N, 2)
        East/north displacement of the ground point seen at a fixed image point per metre of
        height error, metres per metre (``J_g^-1 J_h``; its norm is ``tan(incidence)`` for a
        frame or pushbroom view); the DEM part is ``sigma_DEM^2`` times its outer product.
    """

    lon: Float64Array
    lat: Float64Array
    h: Float64Array
    model: Float64Array
    dem: Float64Array
    displacement: Float64Array

    @property
    def covariance(self) -> Float64Array:
        """(N, 2, 2) total east/north covariance, square metres."""
        return self.model + self.dem

    @property
    def sigma(self) -> Float64Array:
        """(N,) the predicted horizontal error: radial RMS ``sqrt(trace)``, metres."""
        c = self.covariance
        return np.sqrt(c[:, 0, 0] + c[:, 1, 1])


def _points(model: SensorModel, ground: Any, image: Any) -> tuple[Float64Array, ...]:
    if (ground is None) == (image is None):
        raise ValueError("ground_error: give ground=(lon, lat, h) or image=(row, col, h)")
    if ground is not None:
        lon, lat, h = broadcast_float64(lon=ground[0], lat=ground[1], h=ground[2])
    else:
        row, col, hh = broadcast_float64(row=image[0], col=image[1], h=image[2])
        (lon, lat, h), _ = model.backproject_with_status(row.ravel(), col.ravel(), hh.ravel())
    return (np.asarray(lon, np.float64).ravel(), np.asarray(lat, np.float64).ravel(),
            np.asarray(h, np.float64).ravel())


def ground_error(
    model: SensorModel,
    names: Sequence[str],
    covariance: ArrayLike,
    *,
    ground: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    image: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    dem_sigma: ArrayLike = 0.0,
    location_sigma_m: float = 0.0,
) -> GroundError:
    """Propagate a parameter covariance and a DEM error to the horizontal ground error.

    Parameters
    ----------
    model : SensorModel
        Any model of the protocol: ``partials_ground`` and ``partials_parameters``, nothing
        model-specific.
    names : sequence of str, (K,)
        Parameters of ``model`` the covariance is of (may be empty).
    covariance : array_like, (K, K)
        Their covariance, in their units squared.
    ground : (lon, lat, h), optional
        Ground points, degrees and metres above the WGS84 ellipsoid, broadcast to (N,).
    image : (row, col, h), optional
        Or image points (pixel centres at integers) located at heights ``h``. Exactly one of
        ``ground`` and ``image``.
    dem_sigma : float or array_like, (N,)
        Standard deviation of the DEM heights, metres (0: no DEM term).
    location_sigma_m : float
        A stated location accuracy (1 sigma per horizontal axis, metres) added as ``s^2 I``
        to the model part.

    Returns
    -------
    GroundError
        Per point: the model and DEM parts of the east/north covariance (m^2), the
        displacement per metre of height, and the radial RMS ``sigma``; NaN where the model
        does not project the point or its ground partials are singular.

    Raises
    ------
    KeyError
        A name is not a parameter of ``model``.
    ShapeMismatchError
        ``covariance`` is not (K, K).
    """
    from geoblock.errors import ShapeMismatchError

    names = tuple(names)
    cov = np.asarray(covariance, dtype=np.float64)
    if cov.shape != (len(names), len(names)):
        raise ShapeMismatchError(f"ground_error: {len(names)} names but a covariance of shape "
                                 f"{cov.shape}")
    idx = np.array([model.parameters.index(n) for n in names], dtype=np.intp)
    lon, lat, h = _points(model, ground, image)
    n = lon.size
    sig_dem = np.broadcast_to(np.asarray(dem_sigma, dtype=np.float64), (n,))
    rot = coords.enu_rotation(lon, lat)  # (N, 3, 3) rows e, n, u in ECEF
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        j = model.partials_ground(lon, lat, h) @ np.swapaxes(rot, -1, -2)  # d(r,c)/d(e,n,u)
        a = j[:, :, :2]
        det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
        ok = np.isfinite(det) & (det != 0)
        safe = np.where(ok, det, 1.0)
        inv = np.empty_like(a)
        inv[:, 0, 0] = a[:, 1, 1] / safe
        inv[:, 1, 1] = a[:, 0, 0] / safe
        inv[:, 0, 1] = -a[:, 0, 1] / safe
        inv[:, 1, 0] = -a[:, 1, 0] / safe
        inv[~ok] = np.nan
        disp = np.einsum("nij,nj->ni", inv, j[:, :, 2])  # metres per metre of height
        c_model = np.zeros((n, 2, 2))
        if idx.size:
            g = inv @ model.partials_parameters(lon, lat, h)[:, :, idx]  # (N, 2, K)
            c_model = g @ cov @ np.swapaxes(g, 1, 2)
        c_model = c_model + float(location_sigma_m) ** 2 * np.eye(2)
        c_model[~ok] = np.nan
        c_dem = (sig_dem**2)[:, None, None] * (disp[:, :, None] * disp[:, None, :])
    return GroundError(lon, lat, h, c_model, c_dem, disp)
