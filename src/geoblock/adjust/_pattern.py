"""The CSR pattern of the reduced system (:mod:`geoblock.adjust.normal`, above DENSE_LIMIT).

``S`` couples two images' parameters where a point is seen through both (or the prior couples
them). Its pattern is built once per system, by blocks of columns (each image's parameters,
and each parameter no image owns on its own), and ``N_pp`` and the Schur complement are
summed in place into its data by the kernels, which find an entry by its row's start, the
offset of the column's group among the row group's neighbours and the column's rank in its
group. No triplets, no sorting per linearisation.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse

from geoblock.adjust import _solvers
from geoblock.adjust._kernels import _nb_point_groups, _nb_positions
from geoblock.typing import Float64Array, IndexArray


@dataclass(frozen=True)
class _CsrPattern:
    """The CSR pattern of the reduced system, by blocks of columns (images' parameters):
    group ``a`` is linked to group ``b`` where a point is seen through both (or the prior
    couples them), and the whole ``a x b`` block is then held. ``gptr``/``gnbr`` the group
    graph (CSR, sorted), ``slot_offset`` where each neighbour's columns start in a row of
    its row group, ``local_of`` each column's rank in its group, ``diag`` the positions of
    the diagonal."""

    indptr: IndexArray
    indices: IndexArray
    group_of: IndexArray
    local_of: IndexArray
    gptr: IndexArray
    gnbr: IndexArray
    slot_offset: IndexArray
    diag: IndexArray

    @property
    def lookup(self) -> tuple[IndexArray, IndexArray, IndexArray, IndexArray, IndexArray,
                              IndexArray]:
        return (self.indptr, self.group_of, self.local_of, self.gptr, self.gnbr,
                self.slot_offset)

    def positions(self, rows: IndexArray, cols: IndexArray) -> IndexArray:
        out = np.empty(rows.size, np.intp)
        _nb_positions(np.ascontiguousarray(rows, dtype=np.intp),
                      np.ascontiguousarray(cols, dtype=np.intp), *self.lookup, out)
        return out

    @classmethod
    def build(cls, k: int, gidx: IndexArray, cols: IndexArray, order: IndexArray,
              start: IndexArray, prior_rows: IndexArray, prior_cols: IndexArray
              ) -> _CsrPattern:
        groups = _solvers.block_groups(k, gidx)
        n_groups = groups.shape[0]
        ok = groups >= 0
        group_of = np.zeros(k, np.intp)
        group_of[groups[ok]] = np.nonzero(ok)[0]
        local_of = np.zeros(k, np.intp)
        local_of[groups[ok]] = (np.cumsum(ok, axis=1) - 1)[ok]
        width = ok.sum(axis=1)
        count = np.zeros(start.size - 1, np.intp)
        _nb_point_groups(cols, order, start, group_of, n_groups, True, count,
                         np.empty(0, np.intp))
        keys = np.empty(int(np.sum(count * count)), np.intp)
        _nb_point_groups(cols, order, start, group_of, n_groups, False, count, keys)
        keys = np.unique(np.concatenate([
            keys, np.arange(n_groups) * (n_groups + 1),
            group_of[prior_rows] * n_groups + group_of[prior_cols]]))
        ga, gb = keys // n_groups, keys % n_groups  # sorted by ga, then gb
        gptr = np.concatenate([[0], np.cumsum(np.bincount(ga, minlength=n_groups))])
        w = width[gb]
        cs = np.cumsum(w) - w
        slot_offset = cs - cs[gptr[ga]]
        row_len_group = np.bincount(ga, weights=w, minlength=n_groups).astype(np.intp)
        template = groups[gb][ok[gb]]  # each row group's neighbours' columns, in order
        t_start = np.concatenate([[0], np.cumsum(row_len_group)[:-1]])
        row_len = row_len_group[group_of]
        indptr = np.concatenate([[0], np.cumsum(row_len)]).astype(np.intp)
        idx = np.repeat(t_start[group_of] - indptr[:-1], row_len) + np.arange(indptr[-1])
        indices = template[idx].astype(np.intp)
        pattern = cls(indptr, indices, group_of, local_of, gptr.astype(np.intp),
                      gb.astype(np.intp), slot_offset.astype(np.intp), np.empty(0, np.intp))
        diag = pattern.positions(np.arange(k), np.arange(k))
        return dataclasses.replace(pattern, diag=diag)

    def matrix(self, data: Float64Array, k: int) -> Any:
        """The CSR matrix of ``data`` in this pattern (sorted indices, as SuperLU wants)."""
        out = scipy.sparse.csr_matrix((data, self.indices, self.indptr), shape=(k, k))
        if not out.has_sorted_indices:
            out = out.copy()
            out.sort_indices()
        return out
