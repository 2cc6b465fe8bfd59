"""Tie points from pairs' matches: :func:`join_tracks`.

Matches that share a keypoint are one tie point (a connected component of the graph whose
nodes are the images' keypoints and whose edges are the pairs' kept matches). A track's
reference is its keypoint in its first image (in the order given), measured as detected; the
other images' positions come from their match with the reference, or, where a track links an
image to its reference only through a third one, from a refinement against the reference's
patch. Keypoints of one image at the same position (SIFT's second orientation) are one node.
Tracks holding two keypoints of one image are dropped.

Everything here is a function of the pairs' results in the pair graph's order and of the
keypoints' positions: tie-point ids are numbered in the order of the reference image and
position, so they do not depend on which task finished first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from geoblock.match.pipeline import MatchImage, MatchOptions
    from geoblock.match.results import PairMatches

__all__ = ["join_tracks"]

Refine = Callable[[list[tuple[int, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]],
                  list[tuple[np.ndarray, np.ndarray, np.ndarray]]]


def join_tracks(images: Sequence[MatchImage], keypoints: Sequence[int],
                results: Sequence[PairMatches], pair_index: Sequence[tuple[int, int]],
                options: MatchOptions, sigmas: Sequence[float], refine: Refine,
                positions_b: Sequence[tuple[np.ndarray, np.ndarray]]
                ) -> tuple[dict[str, np.ndarray], int]:
    """Join the kept matches of every pair into tracks.

    Parameters
    ----------
    images : sequence of MatchImage
    keypoints : sequence of int
        Each image's number of keypoints (the pairs' indices point into them).
    results : sequence of PairMatches
        The pairs' results, in the order of ``pair_index``.
    pair_index : sequence of (int, int)
        The images of each pair.
    options : MatchOptions
    sigmas : sequence of float
        Each pair's measurement sigma, pixels.
    refine : callable
        Refines the points a track links to its reference only through a third image: given
        ``[(i, j, row_i, col_i, row_j, col_j), ...]``, returns ``[(row_j, col_j, ok), ...]``.
    positions_b : sequence of (ndarray, ndarray)
        Per result, the position of B's keypoint of each kept match (A's is ``row_a,
        col_a``): the tracks hold the keypoints they use only, not every image's (memory
        in proportion to the matches, not to the block's keypoints).

    Returns
    -------
    columns : dict
        ``id, image, row, col, sigma`` (pixels of the models as given) and ``_order``, the
        measurements' order (by id, then image).
    dropped : int
        Tracks dropped for holding two keypoints of one image.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    sizes = [int(k) for k in keypoints]
    base = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    link_a, link_b, link_rb, link_cb, link_sigma = [], [], [], [], []
    pos_a, pos_b = [], []
    for (i, j), res, s, pb in zip(pair_index, results, sigmas, positions_b, strict=True):
        kept = res.kept
        link_a.append(base[i] + res.index_a[kept])
        link_b.append(base[j] + res.index_b[kept])
        link_rb.append(res.row_b[kept])
        link_cb.append(res.col_b[kept])
        link_sigma.append(np.full(int(kept.sum()), s))
        pos_a.append(np.column_stack([res.row_a[kept], res.col_a[kept]]))
        pos_b.append(np.column_stack([np.asarray(pb[0], float), np.asarray(pb[1], float)]))
    ga, gb = np.concatenate(link_a), np.concatenate(link_b)
    lrb, lcb, lsig = (np.concatenate(v) for v in (link_rb, link_cb, link_sigma))
    # the keypoints the links use, numbered in the order of (image, keypoint)
    used, inverse = np.unique(np.concatenate([ga, gb]), return_inverse=True)
    la, lb = inverse[:ga.size], inverse[ga.size:]
    total = int(used.size)
    image_of = np.searchsorted(base, used, side="right") - 1
    kp_pos = np.empty((total, 2))
    kp_pos[la] = np.concatenate(pos_a)
    kp_pos[lb] = np.concatenate(pos_b)
    # SIFT gives a point with two dominant orientations two keypoints at one position: one
    # node, or its matches with two images would become two tie points measured at the same
    # image position (which the adjustment refuses as coincident points)
    _, first, canon = np.unique(np.column_stack([image_of, kp_pos]), axis=0,
                                return_index=True, return_inverse=True)
    if first.size < total:
        canon = canon.ravel()
        # canonical nodes numbered in the order of (image, keypoint) of their first keypoint
        rank = np.empty(first.size, np.intp)
        rank[np.argsort(first, kind="stable")] = np.arange(first.size)
        la, lb = rank[canon[la]], rank[canon[lb]]
        keep_first = np.sort(first)
        image_of, kp_pos = image_of[keep_first], kp_pos[keep_first]
        total = int(keep_first.size)
    kp_row, kp_col = kp_pos[:, 0], kp_pos[:, 1]
    graph = coo_matrix((np.ones(la.size), (la, lb)), shape=(total, total))
    _, label = connected_components(graph, directed=False)
    nodes = np.arange(total)
    comp = label[nodes]
    # a track with two keypoints of one image is inconsistent: dropped
    pair_key = comp.astype(np.int64) * len(sizes) + image_of[nodes]
    uniq, counts = np.unique(pair_key, return_counts=True)
    bad_comp = np.unique(uniq[counts > 1] // len(sizes))
    good = ~np.isin(comp, bad_comp)
    nodes, comp = nodes[good], comp[good]
    # the reference of a track: its node in the first image (nodes are sorted by image)
    order = np.lexsort((image_of[nodes], comp))
    nodes, comp = nodes[order], comp[order]
    is_ref = np.r_[True, comp[1:] != comp[:-1]]
    ref_node = nodes[is_ref][np.cumsum(is_ref) - 1]
    # positions: the reference's keypoint; others from the link with the reference, if any
    row = kp_row[nodes].copy()
    col = kp_col[nodes].copy()
    sigma = np.zeros(nodes.size)
    link_key = la.astype(np.int64) * total + lb
    node_key = ref_node.astype(np.int64) * total + nodes
    sort = np.argsort(link_key)
    pos = np.searchsorted(link_key[sort], node_key)
    pos = np.minimum(pos, link_key.size - 1)
    direct = link_key[sort][pos] == node_key
    row[direct] = lrb[sort][pos[direct]]
    col[direct] = lcb[sort][pos[direct]]
    sigma[direct] = lsig[sort][pos[direct]]
    # nodes linked to the reference only through others: refined against it now
    keep = np.ones(nodes.size, bool)
    indirect = ~direct & ~is_ref
    if indirect.any():
        ref_img, node_img = image_of[ref_node], image_of[nodes]
        groups = sorted(set(zip(ref_img[indirect].tolist(), node_img[indirect].tolist(),
                                strict=True)))  # per pair of images, in order
        sels = [np.flatnonzero(indirect & (ref_img == i) & (node_img == j)) for i, j in groups]
        jobs = [(i, j, kp_row[ref_node[sel]], kp_col[ref_node[sel]], row[sel], col[sel])
                for (i, j), sel in zip(groups, sels, strict=True)]
        for sel, (r, c, good_ref) in zip(sels, refine(jobs), strict=True):
            row[sel] = r
            col[sel] = c
            keep[sel[~good_ref]] = False
            sigma[sel] = float(np.max(sigmas))
    # tracks left with fewer than two measurements are dropped
    kept_comp = comp[keep]
    uniq, counts = np.unique(kept_comp, return_counts=True)
    keep &= np.isin(comp, uniq[counts >= 2])
    nodes, comp, is_ref = nodes[keep], comp[keep], is_ref[keep]
    row, col, sigma = row[keep], col[keep], sigma[keep]
    # the track's sigma: the largest of its measurements'; ids in the order of the
    # reference image and position
    track_sigma = np.zeros(int(label.max()) + 1 if label.size else 0)
    np.maximum.at(track_sigma, comp, sigma)
    ref_rank = np.lexsort((kp_col[nodes][is_ref], kp_row[nodes][is_ref],
                           image_of[nodes][is_ref]))
    number = np.empty(int(label.max()) + 1 if label.size else 0, np.intp)
    number[comp[is_ref][ref_rank]] = np.arange(ref_rank.size)
    width = max(5, len(str(max(ref_rank.size, 1))))
    ids = np.char.add(options.id_prefix, np.char.zfill(number[comp].astype(str), width))
    img = image_of[nodes]
    offset = np.array([im.offset for im in images], dtype=float).reshape(-1, 2)
    out = {"id": ids, "image": np.array([im.id for im in images], dtype=str)[img],
           "row": row + offset[img, 0], "col": col + offset[img, 1],
           "sigma": track_sigma[comp], "_order": np.lexsort((img, number[comp]))}
    return out, int(bad_comp.size)
