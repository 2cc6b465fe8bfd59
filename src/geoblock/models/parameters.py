"""ParameterSet: a sensor model's adjustable parameters (CSM's parameter table, immutable)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import DTypeLike, NDArray

from geoblock.errors import ModelFormatError, ParameterSetError, SerializationError
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["ParameterSet", "accuracy_or_stored", "covariance_from_information",
           "location_accuracy"]


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
    information : array_like, (P, P), optional
        A-priori information (weight) matrix, the inverse of a covariance, in the parameters'
        units to the power -2: the form in which a smoothness prior (a second-difference
        penalty ``D2^T D2 / s^2``, singular on its own) and an amplitude prior
        (``diag(1 / sigma^2)``) add up. When given it supersedes ``sigmas`` and
        ``covariance`` for an adjustment's pseudo-observations (their weight is exactly this
        matrix, restricted to the adjustable parameters). A parameter whose row is zero has
        no a-priori constraint (free, sigma ``inf``); on the others the matrix must be
        symmetric and positive definite, so that :attr:`prior_covariance` (its inverse there)
        exists. ``sigmas`` defaults to the square roots of that inverse's diagonal (the
        marginal a-priori sigmas). Exclusive with ``covariance``.

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
    information: Float64Array | None
    _information_covariance: Float64Array | None = field(init=False, repr=False, compare=False)

    def __init__(
        self,
        names: Sequence[str],
        values: ArrayLike,
        units: Sequence[str] = (),
        sigmas: ArrayLike | None = None,
        adjustable: ArrayLike | None = None,
        covariance: ArrayLike | None = None,
        information: ArrayLike | None = None,
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
        info: Float64Array | None = None
        info_cov: Float64Array | None = None
        if information is not None:
            if covariance is not None:
                raise ValueError("ParameterSet: give a covariance or an information matrix, "
                                 "not both")
            info = _frozen(information)
            if info.shape != (p, p):
                raise ValueError(
                    f"ParameterSet: information must be ({p}, {p}), got {info.shape}")
            info_cov = covariance_from_information(info, names)
            info_cov.flags.writeable = False
        if covariance is not None:
            cov = _frozen(covariance)
            if cov.shape != (p, p):
                raise ValueError(f"ParameterSet: covariance must be ({p}, {p}), got {cov.shape}")
            if not np.allclose(cov, cov.T, rtol=1e-12, atol=0.0):
                raise ValueError("ParameterSet: covariance is not symmetric")
            sig_default = np.sqrt(np.diag(cov))
        else:
            cov = None
            sig_default = (np.full(p, np.inf) if info_cov is None
                           else np.sqrt(np.diag(info_cov)))
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
            ("information", info),
            ("_information_covariance", info_cov),
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
        """(P, P) a-priori covariance: ``covariance`` if given; with an ``information``
        matrix, its inverse on the parameters it constrains (``inf`` on the diagonal, zeros
        off it, for those whose information row is zero); else ``diag(sigmas**2)``."""
        if self.covariance is not None:
            return self.covariance
        if self._information_covariance is not None:
            return self._information_covariance
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
        return self._derived(values=new)

    def with_sigmas(self, sigmas: ArrayLike, covariance: ArrayLike | None = None) -> ParameterSet:
        """A copy with new a-priori sigmas (and optionally a full covariance); an
        ``information`` matrix is dropped."""
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
        return self._derived(adjustable=mask)

    def _derived(self, values: ArrayLike | None = None,
                 adjustable: ArrayLike | None = None) -> ParameterSet:
        """A copy with new values or adjustable mask, the a-priori part unchanged (an
        information matrix's inverse is not computed again)."""
        values_ = self.values if values is None else values
        adjustable_ = self.adjustable if adjustable is None else adjustable
        if self.information is None:
            return ParameterSet(self.names, values_, self.units, self.sigmas, adjustable_,
                                self.covariance)
        out = ParameterSet(self.names, values_, self.units, self.sigmas, adjustable_)
        object.__setattr__(out, "information", self.information)
        object.__setattr__(out, "_information_covariance", self._information_covariance)
        return out

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
        if self.information is not None:  # banded in practice: the upper triangle's nonzeros
            i, j = np.nonzero(np.triu(self.information))
            out["information"] = {"row": [int(v) for v in i], "col": [int(v) for v in j],
                                  "value": [float(v) for v in self.information[i, j]]}
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ParameterSet:
        """Inverse of :meth:`to_dict`."""
        try:
            sigmas = [np.inf if s is None else float(s) for s in data["sigmas"]]
            information = None
            if data.get("information") is not None:
                packed = data["information"]
                p = len(data["names"])
                information = np.zeros((p, p))
                i = np.asarray(packed["row"], dtype=np.intp)
                j = np.asarray(packed["col"], dtype=np.intp)
                value = np.asarray(packed["value"], dtype=np.float64)
                if not (i.shape == j.shape == value.shape and i.ndim == 1):
                    raise ValueError("information: row, col and value differ in length")
                if i.size and (i.min() < 0 or j.min() < 0 or max(i.max(), j.max()) >= p
                               or np.any(i > j)):
                    raise ValueError(f"information: an index outside the upper triangle of "
                                     f"a ({p}, {p}) matrix")
                information[i, j] = value
                information[j, i] = value
            return cls(
                names=tuple(data["names"]),
                values=np.asarray(data["values"], dtype=np.float64),
                units=tuple(data.get("units", ())),
                sigmas=np.asarray(sigmas, dtype=np.float64),
                adjustable=np.asarray(data.get("adjustable", [True] * len(data["names"])), bool),
                covariance=data.get("covariance"),
                information=information,
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


def covariance_from_information(information: ArrayLike,
                                names: Sequence[str] | None = None) -> Float64Array:
    """The covariance an a-priori information matrix stands for.

    Parameters
    ----------
    information : array_like, (P, P)
        Symmetric, finite; positive definite on the parameters whose row is not zero.
    names : sequence of str, (P,), optional
        Parameter names, for the messages.

    Returns
    -------
    ndarray, (P, P)
        The inverse of ``information`` on the parameters whose row is not zero; ``inf`` on the
        diagonal and 0 off it for the others (free: nothing constrains them).

    Raises
    ------
    ValueError
        Not symmetric or not finite, a negative diagonal, or singular on the constrained
        parameters (a smoothness penalty alone leaves a spline's constant and linear part
        undetermined: add an amplitude term ``diag(1 / sigma^2)``).
    """
    info = np.asarray(information, dtype=np.float64)
    p = info.shape[0]
    label = list(names) if names is not None else [str(k) for k in range(p)]
    if info.ndim != 2 or info.shape != (p, p):
        raise ValueError(f"ParameterSet: information must be square, got {info.shape}")
    if not np.all(np.isfinite(info)):
        raise ValueError("ParameterSet: information must be finite (0 rows for free "
                         "parameters)")
    if not np.allclose(info, info.T, rtol=1e-12, atol=0.0):
        raise ValueError("ParameterSet: information is not symmetric")
    diag = np.diag(info)
    if np.any(diag < 0):
        bad = [n for n, d in zip(label, diag, strict=True) if d < 0]
        raise ValueError(f"ParameterSet: information has a negative diagonal at {bad}")
    on = np.any(info != 0, axis=1)
    cov = np.zeros((p, p))
    free = np.flatnonzero(~on)
    cov[free, free] = np.inf
    if on.any():
        sub = info[np.ix_(on, on)]
        try:
            chol = np.linalg.cholesky(sub)
        except np.linalg.LinAlgError:
            raise ValueError(
                "ParameterSet: information is not positive definite on the parameters it "
                "constrains (a smoothness prior alone leaves a constant or a trend free): add "
                "an amplitude term diag(1/sigma^2), or zero the rows of free parameters"
            ) from None
        inv_l = np.linalg.inv(chol)
        cov[np.ix_(on, on)] = inv_l.T @ inv_l
    return cov


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
