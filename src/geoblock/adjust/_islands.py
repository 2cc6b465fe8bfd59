"""Connectivity of a block, checked before any engine is built (graph work only: no
projection, no matching cost).

The image graph links two images of the adjusted set when a point in the solution (a TP or
HCP measured in two images or more, or a GCP: every such point is one set of unknowns that
all its images share) is measured in both. Its connected components (``scipy.sparse.csgraph``)
are independent least-squares problems: nothing in the normal equations couples them, so one
cannot tell where one group lies relative to another except through what each holds on its
own (GCPs, the DEM, the a-priori sigmas). A block of several components is refused by
default (:func:`check_block`), naming each group; ``components="separate"`` adjusts each
alone and merges the results.

Images with fewer observations than free parameters are named first: an image's
observations are counted as two per measurement of a GCP, TP or HCP in the solution, its
free parameters as its adjustable parameters without a finite a-priori sigma (a parameter
with a prior has its pseudo-observation); an image with adjustable parameters and no
measurement at all is named too.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph

from geoblock.adjust.observations import lookup
from geoblock.adjust.problem import Block
from geoblock.adjust.weights import parameter_prior
from geoblock.errors import AdjustmentError, TooFewPointsError
from geoblock.typing import BoolArray, IndexArray

__all__ = ["COMPONENTS", "Connectivity", "block_components", "check_block"]

#: how :func:`~geoblock.adjust.adjust` treats a block of several disconnected groups:
#: ``"refuse"`` (default: an AdjustmentError naming the groups), ``"separate"`` (each group
#: adjusted alone, the results merged) or ``"joint"`` (one system holding all the groups, as
#: before the check: the same estimates, one pooled sigma0)
COMPONENTS = ("refuse", "separate", "joint")


@dataclass(frozen=True)
class Connectivity:
    """The image graph of a block.

    Attributes
    ----------
    ids : tuple of str
        The adjusted images, in the block's order.
    label : ndarray of intp, (I,)
        Component of each image; components numbered by their first image.
    measurements : ndarray of intp, (I,)
        GCP/TP/HCP measurements of each image in the solution.
    links : int
        Image pairs sharing at least one point (edges of the graph).
    """

    ids: tuple[str, ...]
    label: IndexArray
    measurements: IndexArray
    links: int

    @property
    def n_components(self) -> int:
        return int(self.label.max()) + 1 if self.label.size else 0

    def groups(self, mask: BoolArray | None = None) -> list[tuple[str, ...]]:
        """The image ids of each component (only the images where ``mask`` (I,) is True),
        largest first (ties: by first image); empty components left out."""
        ids = np.array(self.ids)
        keep = np.ones(ids.size, bool) if mask is None else np.asarray(mask, bool)
        order = np.argsort(self.label[keep], kind="stable")
        label, kept = self.label[keep][order], ids[keep][order]
        if label.size == 0:
            return []
        starts = np.flatnonzero(np.r_[True, label[1:] != label[:-1]])
        groups = [tuple(g.tolist()) for g in np.split(kept, starts[1:])]
        return sorted(groups, key=lambda g: -len(g))


def _solution_rows(block: Block, ids: Sequence[str]) -> IndexArray:
    meas = block.measurements
    return np.flatnonzero(np.isin(meas.image, list(ids))
                          & np.isin(meas.kind, ("gcp", "tp", "hcp")))


def block_components(block: Block, ids: Sequence[str] | None = None) -> Connectivity:
    """The image graph of ``block`` (or of the images ``ids``) and its components.

    Graph work only: O(measurements log measurements), no model is evaluated.
    """
    ids = tuple(block.image_ids if ids is None else ids)
    meas = block.measurements
    sel = _solution_rows(block, ids)
    n = len(ids)
    image = lookup(np.array(ids), meas.image[sel])
    _, point = np.unique(meas.id[sel], return_inverse=True)
    counts = np.bincount(image, minlength=n)
    label, links = _components(image, point, n)
    return Connectivity(ids=ids, label=label, measurements=counts.astype(np.intp),
                        links=links)


def _components(image: IndexArray, point: IndexArray, n: int) -> tuple[IndexArray, int]:
    """Component label (I,) of each of ``n`` images, numbered by first image, and the number
    of linked image pairs, from the image and point (M,) of each measurement."""
    # star edges: each measurement to the first image of its point (connectivity only)
    order = np.lexsort((image, point))
    p_sorted, i_sorted = point[order], image[order]
    first = np.ones(p_sorted.size, bool)
    first[1:] = p_sorted[1:] != p_sorted[:-1]
    root = i_sorted[np.maximum.accumulate(np.where(first, np.arange(p_sorted.size), 0))]
    keep = root != i_sorted
    graph = scipy.sparse.coo_matrix(
        (np.ones(int(keep.sum())), (root[keep], i_sorted[keep])), shape=(n, n)).tocsr()
    _, label = scipy.sparse.csgraph.connected_components(graph, directed=False)
    # renumbered by first image, so that the labels do not depend on scipy's traversal
    _, first_of, relabel = np.unique(label, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first_of))
    sym = (graph + graph.T).tocsr()
    sym.data[:] = 1.0
    return rank[relabel].astype(np.intp), int(sym.nnz // 2)


def _listed(group: Sequence[str], limit: int = 5) -> str:
    head = ", ".join(group[:limit])
    return head + (f" ... ({len(group)} images)" if len(group) > limit else
                   f" ({len(group)} image{'s' if len(group) > 1 else ''})")


def check_block(block: Block, components: str) -> list[tuple[str, ...]]:
    """The groups of images to adjust (one per solution), after the connectivity checks.

    Parameters
    ----------
    block : Block
    components : {"refuse", "separate", "joint"}
        See :data:`COMPONENTS`.

    Returns
    -------
    list of tuple of str
        ``[block.image_ids]`` for a connected block (or ``"joint"``), else one tuple per
        component (``"separate"``), largest first.

    Raises
    ------
    TooFewPointsError
        Images with fewer observations than free parameters (all named, with the counts).
    AdjustmentError
        Several components and ``components="refuse"``: each group named (its first ids and
        its count) and the option that adjusts them separately.
    """
    if components not in COMPONENTS:
        raise AdjustmentError(f"adjust: components must be one of {COMPONENTS}, got "
                              f"{components!r}")
    ids = block.image_ids
    if _solution_rows(block, ids).size == 0:
        return [ids]  # the engine says there is nothing to adjust from
    conn = block_components(block, ids)
    short = []
    for i, image in enumerate(ids):
        mask, cov = parameter_prior(block.models[image], block.sigmas.get(image, {}))
        adj = np.flatnonzero(mask)
        if adj.size == 0:
            continue
        free = int(np.sum(~np.isfinite(np.diag(cov)[adj])))
        n_obs = 2 * int(conn.measurements[i])
        if n_obs == 0 or free > n_obs:
            short.append(f"{image} ({conn.measurements[i]} measurement(s), {n_obs} "
                         f"observations for {free} free of {adj.size} adjustable "
                         "parameters)")
    if short:
        listed = "; ".join(short[:8]) + (f"; and {len(short) - 8} more" if len(short) > 8
                                         else "")
        raise TooFewPointsError(
            f"block: {len(short)} image(s) without enough points (no GCP or TP measurement, "
            f"or fewer observations, two per measurement, than free parameters): {listed}; "
            "add GCPs or TPs, give their parameters a-priori sigmas, or fix them")
    # an image with no measurement (and, past the check above, nothing to adjust) links
    # nothing and changes nothing: not a group of its own
    idle = conn.measurements == 0
    n_groups = np.unique(conn.label[~idle]).size
    if n_groups <= 1 or components == "joint":
        return [ids]
    groups = conn.groups(~idle)
    extra = tuple(np.array(ids)[idle].tolist())
    if components == "separate":
        return [groups[0] + extra, *groups[1:]]
    if components == "separate":
        return groups
    listed = "; ".join(f"group {c + 1}: {_listed(g)}" for c, g in enumerate(groups[:6]))
    if len(groups) > 6:
        listed += f"; and {len(groups) - 6} more groups"
    raise AdjustmentError(
        f"block: the images form {len(groups)} disconnected groups (no GCP or tie point is "
        f"measured in images of two groups): {listed}. Nothing ties the groups to each other: "
        "add tie points between them, or adjust each group alone with "
        "adjust(..., components=\"separate\") (geoblock adjust --components separate)")
