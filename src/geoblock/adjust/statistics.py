"""Accuracy statistics of check-point and control-point errors (Aguilar et al., Table 3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoblock.typing import ArrayLike

__all__ = ["AccuracyStats"]


def _signed_max(x: np.ndarray) -> float:
    """The value of largest magnitude, with its sign (NaN for no values)."""
    return float(x[np.argmax(np.abs(x))]) if x.size else float("nan")


@dataclass(frozen=True)
class AccuracyStats:
    """RMSE, mean (bias) and maximum error of planimetric errors, metres.

    Errors are *estimated minus reference* along local east (E) and north (N). ``max_e`` and
    ``max_n`` keep their sign, as in Aguilar et al.'s Table 3; ``rmse_2d`` is
    ``sqrt(rmse_e**2 + rmse_n**2)`` (their eq. 5).
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

    @classmethod
    def from_errors(cls, de: ArrayLike, dn: ArrayLike) -> AccuracyStats:
        """Statistics of the finite error pairs ``(de, dn)`` (metres)."""
        de = np.asarray(de, dtype=np.float64).ravel()
        dn = np.asarray(dn, dtype=np.float64).ravel()
        ok = np.isfinite(de) & np.isfinite(dn)
        de, dn = de[ok], dn[ok]
        if de.size == 0:
            nan = float("nan")
            return cls(0, nan, nan, nan, nan, nan, nan, nan, nan)
        rmse_e = float(np.sqrt(np.mean(de**2)))
        rmse_n = float(np.sqrt(np.mean(dn**2)))
        return cls(
            n=int(de.size),
            rmse_e=rmse_e,
            rmse_n=rmse_n,
            rmse_2d=float(np.hypot(rmse_e, rmse_n)),
            mean_e=float(de.mean()),
            mean_n=float(dn.mean()),
            max_e=_signed_max(de),
            max_n=_signed_max(dn),
            max_2d=float(np.max(np.hypot(de, dn))),
        )

    def as_row(self) -> str:
        """One line: ``n  RMSE E N 2D  max E N  mean E N`` (metres)."""
        return (
            f"{self.n:4d}  RMSE E {self.rmse_e:8.3f} N {self.rmse_n:8.3f} 2D {self.rmse_2d:8.3f}"
            f"  max E {self.max_e:8.3f} N {self.max_n:8.3f}"
            f"  mean E {self.mean_e:8.3f} N {self.mean_n:8.3f}"
        )
