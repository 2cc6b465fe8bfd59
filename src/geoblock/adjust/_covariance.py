"""Selected parameter cofactors (:meth:`geoblock.adjust.normal.NormalSystem.parameter_cofactor`).

A block of 10^4 images has some 6e4 parameters: their full cofactor matrix ``Q_pp = S^-1``
would take 29 GB. The covariances a report needs are those of a few images and of the points
they see: the requested columns of ``Q_pp`` are solved from the reduced system's
factorisation (``S X = E``, ``E`` the unit columns, :data:`~geoblock.adjust._solvers.
COLUMN_CHUNK` at a time) and only their rows among themselves are kept, ``Q_pp[C, C]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoblock.typing import Float64Array, IndexArray

__all__ = ["SelectedCofactor"]


@dataclass(frozen=True)
class SelectedCofactor:
    """The parameter cofactor ``Q_pp`` restricted to some columns and their rows.

    Parameters
    ----------
    n_params : int
        ``K``, the number of parameters of the system.
    columns : ndarray of intp, (n,)
        The parameters held, sorted, unique (global indices).
    q : ndarray, (n, n)
        ``Q_pp[columns][:, columns]`` (cofactor: squared units of the parameters, relative
        to the whitening of the observations).
    """

    n_params: int
    columns: IndexArray
    q: Float64Array

    @property
    def pos(self) -> IndexArray:
        """(K,) the position of each parameter in :attr:`columns` (-1: not held)."""
        out = np.full(self.n_params, -1, np.intp)
        out[self.columns] = np.arange(self.columns.size)
        return out

    def held(self, cols: IndexArray) -> np.ndarray:
        """Whether each parameter of ``cols`` (any shape; -1 counts as held) is held."""
        c = np.asarray(cols, dtype=np.intp)
        return (c < 0) | (self.pos[np.maximum(c, 0)] >= 0)

    def block(self, i_cols: IndexArray, j_cols: IndexArray | None = None) -> Float64Array:
        """``Q_pp[i_cols][:, j_cols]`` (``j_cols`` default ``i_cols``): NaN where either
        parameter is not held, 0 where either index is -1 (padding)."""
        i = np.asarray(i_cols, dtype=np.intp)
        j = i if j_cols is None else np.asarray(j_cols, dtype=np.intp)
        pos = self.pos
        pi, pj = pos[np.maximum(i, 0)], pos[np.maximum(j, 0)]
        out = self.q[np.maximum(pi, 0)[:, None], np.maximum(pj, 0)[None, :]]
        out = np.where((pi[:, None] < 0) | (pj[None, :] < 0), np.nan, out)
        return np.where((i[:, None] < 0) | (j[None, :] < 0), 0.0, out)

    def diagonal(self) -> Float64Array:
        """(K,) the cofactor variances, NaN for the parameters not held."""
        out = np.full(self.n_params, np.nan)
        out[self.columns] = np.diag(self.q)
        return out
