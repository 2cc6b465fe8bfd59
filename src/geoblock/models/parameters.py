"""ParameterSet: a sensor model's adjustable parameters (CSM's parameter table, immutable)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import DTypeLike, NDArray

from geoblock.errors import ModelFormatError, ParameterSetError, SerializationError
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["ParameterSet", "accuracy_or_stored", "location_accuracy"]


def _frozen(a: ArrayLike, dtype: DTypeLike = np.float64) -> NDArray[Any]:
    out = np.array(a, dtype=dtype)
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False, init=False, repr=False)
class ParameterSet:
    """Names, units, values and a-priori accuracy of a model's parameters.

    Parameters
    ----------
    names : sequence of str, (P,)
        snake_case, unit-free, unique (``a0``, ``roll_bias``).
    values : array_like, (P,)
        Current values, in ``units``.
    units : sequence of str, (P,), optional
        Unit of each parameter (``"px"``, ``"rad"``, ``"m"``, ``"1"``); default ``"1"``.
    sigmas : array_like, (P,), optional
        A-priori standard deviations, in ``units``. ``inf`` (the default) means no a-priori
        constraint: an adjustment treats the parameter as free. Adjustments add finite sigmas
        as weighted pseudo-observations.
    adjustable : array_like of bool, (P,), optional
        Which parameters an adjustment may change (default all).
    covariance : array_like, (P, P), optional
        Full a-priori covariance; when given it supersedes ``sigmas`` (whose squares must be
        its diagonal).

    Notes
    -----
    Immutable: :meth:`with_values` returns a new set. Arrays are read-only.
    """

    names: tuple[str, ...]
    values: Float64Array
    units: tuple[str, ...]
    sigmas: Float64Array
    adjustable: NDArray[np.bool_]
    covariance: Float64Array | None

    def __init__(
        self,
        names: Sequence[str],
        values: ArrayLike,
        units: Sequence[str] = (),
        sigmas: ArrayLike | None = None,
        adjustable: ArrayLike | None = None,
        covariance: ArrayLike | None = None,
    ) -> None:
        names = tuple(str(n) for n in names)
        p = len(names)
        if len(set(names)) != p:
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"ParameterSet: duplicate parameter names {dup}")
        values_ = _frozen(values)
        if values_.shape != (p,):
            raise ValueError(f"ParameterSet: {p} names but values of shape {values_.shape}")
        units = tuple(units) if units else ("1",) * p
        if len(units) != p:
            raise ValueError(f"ParameterSet: {p} names but {len(units)} units")
        cov: Float64Array | None
        if covariance is not None:
            cov = _frozen(covariance)
            if cov.shape != (p, p):
                raise ValueError(f"ParameterSet: covariance must be ({p}, {p}), got {cov.shape}")
            if not np.allclose(cov, cov.T, rtol=1e-12, atol=0.0):
                raise ValueError("ParameterSet: covariance is not symmetric")
            sig_default = np.sqrt(np.diag(cov))
        else:
            cov = None
            sig_default = np.full(p, np.inf)
        sigmas_ = _frozen(sig_default if sigmas is None else sigmas)
        if sigmas_.shape != (p,):
            raise ValueError(f"ParameterSet: {p} names but sigmas of shape {sigmas_.shape}")
        if np.any(np.isnan(sigmas_)) or np.any(sigmas_ <= 0):
            bad = [n for n, s in zip(names, sigmas_, strict=True) if not s > 0]
            raise ValueError(f"ParameterSet: sigmas must be > 0 (inf for free); bad: {bad}")
        adjustable_ = _frozen(np.ones(p, bool) if adjustable is None else adjustable, dtype=bool)
        if adjustable_.shape != (p,):
            raise ValueError(
                f"ParameterSet: {p} names but adjustable of shape {adjustable_.shape}")
        for name, value in (
            ("names", names),
            ("values", values_),
            ("units", units),
            ("sigmas", sigmas_),
            ("adjustable", adjustable_),
            ("covariance", cov),
        ):
            object.__setattr__(self, name, value)

    # -- access -------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of parameter ``name``; ``KeyError`` naming the known ones otherwise."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no parameter {name!r}; parameters are {list(self.names)}") from None

    def __getitem__(self, name: str) -> float:
        return float(self.values[self.index(name)])

    def as_dict(self) -> dict[str, float]:
        """``{name: value}``."""
        return {n: float(v) for n, v in zip(self.names, self.values, strict=True)}

    @property
    def prior_covariance(self) -> Float64Array:
        """(P, P) a-priori covariance: ``covariance`` if given, else ``diag(sigmas**2)``."""
        if self.covariance is not None:
            return self.covariance
        return np.diag(self.sigmas**2)

    # -- updates ------------------------------------------------------------------------------
    def with_values(self, values: ArrayLike | Mapping[str, float]) -> ParameterSet:
        """A copy with new values: an array of shape (P,) or a ``{name: value}`` mapping."""
        if isinstance(values, Mapping):
            new = np.array(self.values)
            for name, value in values.items():
                new[self.index(name)] = value
        else:
            new = np.asarray(values, dtype=np.float64)
            if new.shape != (len(self),):
                raise ValueError(
                    f"with_values: expected {len(self)} values {list(self.names)}, "
                    f"got shape {new.shape}"
                )
        return ParameterSet(
            self.names, new, self.units, self.sigmas, self.adjustable, self.covariance
        )

    def with_sigmas(self, sigmas: ArrayLike, covariance: ArrayLike | None = None) -> ParameterSet:
        """A copy with new a-priori sigmas (and optionally a full covariance)."""
        return ParameterSet(
            self.names, self.values, self.units, sigmas, self.adjustable, covariance
        )

    def with_adjustable(self, adjustable: ArrayLike | Sequence[str]) -> ParameterSet:
        """A copy with a new adjustable mask, given as booleans (P,) or parameter names."""
        mask = np.asarray(adjustable)
        if mask.dtype != bool:
            names = [str(n) for n in np.atleast_1d(mask)]
            mask = np.zeros(len(self), bool)
            for n in names:
                mask[self.index(n)] = True
        return ParameterSet(self.names, self.values, self.units, self.sigmas, mask, self.covariance)

    # -- serialisation ------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary (``null`` for an infinite sigma)."""
        out: dict[str, Any] = {
            "names": list(self.names),
            "values": [float(v) for v in self.values],
            "units": list(self.units),
            "sigmas": [None if np.isinf(s) else float(s) for s in self.sigmas],
            "adjustable": [bool(a) for a in self.adjustable],
        }
        if self.covariance is not None:
            out["covariance"] = [[float(v) for v in row] for row in self.covariance]
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ParameterSet:
        """Inverse of :meth:`to_dict`."""
        try:
            sigmas = [np.inf if s is None else float(s) for s in data["sigmas"]]
            return cls(
                names=tuple(data["names"]),
                values=np.asarray(data["values"], dtype=np.float64),
                units=tuple(data.get("units", ())),
                sigmas=np.asarray(sigmas, dtype=np.float64),
                adjustable=np.asarray(data.get("adjustable", [True] * len(data["names"])), bool),
                covariance=data.get("covariance"),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise SerializationError(f"invalid parameter set {dict(data)!r}: {exc}") from exc

    @classmethod
    def empty(cls) -> ParameterSet:
        """A set with no parameters."""
        return cls((), np.zeros(0))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ParameterSet):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash((self.names, self.values.tobytes()))

    def __repr__(self) -> str:
        body = ", ".join(
            f"{n}={v:.6g} {u}"
            for n, v, u in zip(self.names, self.values, self.units, strict=True)
        )
        return f"ParameterSet({body})"


# ------------------------------------------------------------------ location accuracy
def location_accuracy(
    value: Any, where: str, error: type[Exception] = ModelFormatError
) -> float:
    """``value`` as a location accuracy (1 sigma, metres): a finite number > 0.

    Parameters
    ----------
    value : Any
        Anything ``float()`` accepts.
    where : str
        What the value is (``"LinescanModel.location_accuracy_m"``); starts the message.
    error : type of Exception
        Raised otherwise (default :class:`~geoblock.errors.ModelFormatError`; a
        :class:`~geoblock.errors.ParameterSetError` when a parameter set asks for it).

    Raises
    ------
    error
        ``"{where}: must be finite and > 0 metres, got {value!r}"``.
    """
    try:
        accuracy = float(value)
    except (TypeError, ValueError):
        accuracy = float("nan")
    if not (np.isfinite(accuracy) and accuracy > 0):
        raise error(f"{where}: must be finite and > 0 metres, got {value!r}")
    return accuracy


def accuracy_or_stored(
    given: Any, stored: float | None, model: str, set_name: str,
    advice: str = "accuracy_m= (1 sigma, metres)",
) -> float:
    """The accuracy a parameter set derives its sigmas from: ``given`` (an ``accuracy_m``
    option) unless None, else the model's ``stored`` ``location_accuracy_m``.

    Parameters
    ----------
    given : Any
        The option's value, or None.
    stored : float or None
        The model's ``location_accuracy_m``.
    model : str
        The model, as messages name it (``"LinescanModel 'linescan'"``).
    set_name : str
        The parameter set asked for (``"dg"``).
    advice : str
        What to pass instead, ending the message of the missing-accuracy error.

    Returns
    -------
    float
        Validated by :func:`location_accuracy`.

    Raises
    ------
    ParameterSetError
        Both are None, or the accuracy is not finite and > 0.
    """
    accuracy = stored if given is None else given
    if accuracy is None:
        raise ParameterSetError(
            f"{model}: parameter set {set_name!r} derives its a-priori sigmas from the "
            "product's location accuracy, which this model does not know (location_accuracy_m "
            f"is None): pass {advice}"
        )
    return location_accuracy(accuracy, f"{model}, parameter set {set_name!r}: accuracy_m",
                             ParameterSetError)
