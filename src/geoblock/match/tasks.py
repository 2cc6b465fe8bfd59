"""Matching as tasks: the steps of :func:`geoblock.match.match_images` on any dask scheduler.

The work of a block is cut into tasks that each read only the pixels they need, so that they
run on local threads, local processes or the workers of a dask.distributed cluster alike:

* **keypoints** - one task per image: SIFT on the image's part of its selected pairs' overlaps,
  read in chunks of 2048 px (:func:`~geoblock.match.features.detect_keypoints`);
* **pairs** - one task per selected pair: steps 2-6 of :mod:`geoblock.match.pipeline` with the
  two images' keypoints; the sub-pixel refinement reads the pixels tile by tile
  (:func:`refine_in_tiles`: a ``TILE_PX`` tile of A and the part of B its matches fall in), so
  that a task's memory does not grow with the images;
* **links** - one task per pair of images a track links only through a third image: the same
  refinement of those points.

The tracks are joined after every pair is done, from the pairs' results in the order of the
pair graph, never in the order the tasks finish: tie-point ids are numbered from the images'
order and the keypoints' positions, so the same inputs give the same CSV, byte for byte, on
every scheduler (``synchronous``, ``threads``, ``processes``, a ``distributed.Client``).

What a worker needs travels with its task, pickled: each image's :class:`MatchImage` (the
image file's path, re-opened on the worker; the model's parameters) and the DEM (a raster DEM
travels as its path and reopens there): the files must be readable at the same paths on
every worker (a shared file system).

Memory per task: a keypoint task, SIFT's working memory of one 2048 x 2048 px chunk (about
60 bytes a pixel, 250 MB) and the image's keypoints (about 600 bytes each: 12 MB for 20000);
a pair task, both images' keypoints (24 MB at 20000 each), the candidates' arrays (about
150 bytes each; only the kept ones travel back unless ``MatchOptions.keep_candidates``) and
one tile pair of pixels as float64 (about 2 x 1100^2 x 8 bytes = 20 MB for 1024 px tiles,
more where B's pixels are smaller than A's).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from geoblock.errors import MatchError
from geoblock.match.features import Keypoints, detect_keypoints
from geoblock.match.refine import RefineStatus, refine_matches

if TYPE_CHECKING:
    from geoblock.dem.protocol import DemSource
    from geoblock.match.geometry import Overlap
    from geoblock.match.pipeline import MatchImage, MatchOptions
    from geoblock.match.results import PairMatches

__all__ = ["SCHEDULERS", "TILE_PX", "match_pairs", "refine_in_tiles", "refine_links",
           "run_tasks"]

#: The local dask schedulers by name (else a ``distributed.Client`` or its address).
SCHEDULERS = ("threads", "processes", "synchronous")
#: Side of the tiles of A the refinement reads at a time, pixels.
TILE_PX = 1024


# ============================================================================== scheduling
def _client(scheduler: Any) -> Any:
    """The distributed Client ``scheduler`` is (or connects to), None for a local one."""
    if scheduler is None or scheduler in SCHEDULERS:
        return None
    if isinstance(scheduler, str):
        raise MatchError(f"scheduler {scheduler!r} is none of {', '.join(SCHEDULERS)} or a "
                         "distributed.Client (give an address to the command line's "
                         "--scheduler)")
    if "distributed" in sys.modules:
        from distributed import Client

        if isinstance(scheduler, Client):
            return scheduler
    raise MatchError(f"scheduler {scheduler!r} is none of {', '.join(SCHEDULERS)} or a "
                     "distributed.Client")


def run_tasks(tasks: Mapping[str, Any], scheduler: Any = "threads",
              done: Callable[[str, Any], None] | None = None) -> dict[str, Any]:
    """Compute named dask ``Delayed`` objects on a scheduler, reporting each as it finishes.

    Parameters
    ----------
    tasks : mapping of str to dask.delayed.Delayed
        The results wanted, by name (their dependencies are computed too, on the workers).
    scheduler : {"threads", "processes", "synchronous"} or distributed.Client
    done : callable, optional
        Called as ``done(name, value)`` in the calling thread as each result arrives (in the
        order they finish: for progress, never for the results' order).

    Returns
    -------
    dict
        ``name -> value``, in the order of ``tasks``.

    Raises
    ------
    MatchError
        An unknown scheduler; what a task raises is re-raised.
    """
    import dask

    names = list(tasks)
    report = done or (lambda name, value: None)
    client = _client(scheduler)
    if client is not None:
        from distributed import as_completed

        futures = client.compute([tasks[n] for n in names])
        name_of = {f.key: n for f, n in zip(futures, names, strict=True)}
        out: dict[str, Any] = {}
        for fut in as_completed(futures):
            name = name_of[fut.key]
            out[name] = fut.result()
            fut.release()
            report(name, out[name])
        return {n: out[n] for n in names}
    from dask.callbacks import Callback

    wanted = {tasks[n].key: n for n in names}

    class _Done(Callback):
        def _posttask(self, key: Any, result: Any, dsk: Any, state: Any, worker: Any
                      ) -> None:
            if key in wanted:
                report(wanted[key], result)

    with _Done():
        values = dask.compute(*[tasks[n] for n in names], scheduler=scheduler or "threads")
    return dict(zip(names, values, strict=True))


# ============================================================================== pixels
def refine_in_tiles(a: MatchImage, b: MatchImage, row_a: np.ndarray, col_a: np.ndarray,
                    row_b: np.ndarray, col_b: np.ndarray, jacobian: np.ndarray,
                    options: MatchOptions, *, tile_px: int = TILE_PX
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~geoblock.match.refine.refine_matches` reading the pixels a tile at a time.

    The points are grouped by the ``tile_px`` tile of A they fall in; per tile, A's pixels
    around its points and B's around their starts (each padded by the correlation's reach,
    B's scaled by the local affinity) are read and refined: memory is one tile pair, whatever
    the images' size; the results are those of a refinement on the whole images.

    Parameters
    ----------
    a, b : MatchImage
    row_a, col_a : ndarray, (N,)
        A's points, pixels of A's image.
    row_b, col_b : ndarray, (N,)
        Starting positions in B, pixels of B's image.
    jacobian : ndarray, (N, 2, 2)
        Local affinity A -> B.
    options : MatchOptions
        ``half_px``, ``refine_search_px`` and ``min_score``.
    tile_px : int
        Side of A's tiles, pixels.

    Returns
    -------
    row, col, score : ndarray, (N,)
        The refined positions in B (the start where the refinement failed), pixels of B's
        image, and the correlation.
    status : ndarray of uint8, (N,)
        :class:`~geoblock.match.refine.RefineStatus`.
    """
    from geoblock.io.images import read_band

    n = row_a.size
    row, col = row_b.astype(float).copy(), col_b.astype(float).copy()
    score = np.full(n, np.nan)
    status = np.full(n, RefineStatus.NO_DATA, np.uint8)
    if not n:
        return row, col, score, status
    reach = 2 * (options.half_px + options.refine_search_px + 4)
    tile = (np.floor(row_a / tile_px).astype(np.int64) << 32) + np.floor(
        col_a / tile_px).astype(np.int64)
    keys, inverse = np.unique(tile, return_inverse=True)
    shape_a = (int(a.image.shape[0]), int(a.image.shape[1]))
    shape_b = (int(b.image.shape[0]), int(b.image.shape[1]))
    for t in range(keys.size):  # per tile, not per point: each refinement is vectorised
        sel = np.flatnonzero(inverse == t)
        wa = _bbox(row_a[sel], col_a[sel], reach, shape_a)
        stretch = float(np.max(np.abs(jacobian[sel]).sum(axis=2)))
        wb = _bbox(row_b[sel], col_b[sel], reach * max(1.0, stretch), shape_b)
        if wa is None or wb is None:
            continue
        ref = refine_matches(read_band(a.image, wa), read_band(b.image, wb),
                             row_a[sel] - wa[0], col_a[sel] - wa[2], row_b[sel] - wb[0],
                             col_b[sel] - wb[2], jacobian[sel], half_px=options.half_px,
                             search_px=options.refine_search_px, min_score=options.min_score)
        row[sel] = ref.row + wb[0]
        col[sel] = ref.col + wb[2]
        score[sel] = ref.score
        status[sel] = ref.status
    return row, col, score, status


def _bbox(row: np.ndarray, col: np.ndarray, pad: float, shape: tuple[int, int]
          ) -> tuple[int, int, int, int] | None:
    """The window enclosing the points, padded, clipped to the image (None: empty)."""
    ok = np.isfinite(row) & np.isfinite(col)
    if not ok.any():
        return None
    p = int(math.ceil(pad))
    r0 = max(0, int(math.floor(float(row[ok].min()))) - p)
    r1 = min(shape[0], int(math.ceil(float(row[ok].max()))) + p + 1)
    c0 = max(0, int(math.floor(float(col[ok].min()))) - p)
    c1 = min(shape[1], int(math.ceil(float(col[ok].max()))) + p + 1)
    return (r0, r1, c0, c1) if r1 > r0 and c1 > c0 else None


# ============================================================================== the tasks
def _detect(im: MatchImage, window: tuple[int, int, int, int], options: MatchOptions
            ) -> Keypoints:
    """Keypoints of one image in its part of the overlaps (a task; none: its pairs fail)."""
    return detect_keypoints(im.image, window, max_keypoints=options.max_keypoints,
                            cell_px=options.cell_px,
                            contrast_threshold=options.contrast_threshold)


def _count(kp: Keypoints) -> int:
    """How many keypoints an image has (the keypoints stay with the workers)."""
    return len(kp)


def _pair(a: MatchImage, kp_a: Keypoints, b: MatchImage, kp_b: Keypoints, dem: DemSource,
          lap: Overlap, search: float, options: MatchOptions
          ) -> tuple[PairMatches | None, list[str], str | None,
                     tuple[np.ndarray, np.ndarray]]:
    """Match one pair (a task): its result (None if it failed), its messages, why it failed
    (a pair that cannot be matched does not stop the block's other pairs) and the positions
    of B's keypoints of the kept matches (for the tracks)."""
    from geoblock.match.pipeline import _match_pair

    messages: list[str] = []
    none = (np.zeros(0), np.zeros(0))
    if not len(kp_a) or not len(kp_b):
        empty = a if not len(kp_a) else b
        return None, messages, (f"{empty.name}: no SIFT keypoint found in its overlap with "
                                "the other images (a flat, saturated or nodata area?)"), none
    try:
        res = _match_pair(a, kp_a, b, kp_b, dem, lap, search, options, messages.append)
    except MatchError as exc:
        text = str(exc)
        if a.name not in text and b.name not in text:
            text = f"{a.name} and {b.name}: {text}"
        return None, messages, text, none
    kept = res.index_b[res.kept]
    return (res if options.keep_candidates else res.compact()), messages, None, (
        kp_b.row[kept], kp_b.col[kept])


def _link(a: MatchImage, b: MatchImage, dem: DemSource, row_a: np.ndarray, col_a: np.ndarray,
          row_b: np.ndarray, col_b: np.ndarray, options: MatchOptions
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Refine points of B linked to A's keypoints through a third image (a task)."""
    from geoblock.match.geometry import local_affine

    jac = local_affine(a.model, b.model, dem, row_a, col_a)
    row, col, _, status = refine_in_tiles(a, b, row_a, col_a, row_b, col_b, jac, options)
    return row, col, status == RefineStatus.CONVERGED


def match_pairs(images: Sequence[MatchImage], dem: DemSource,
                pairs: Sequence[tuple[int, int, Overlap]], searches: Sequence[float],
                windows: Sequence[tuple[int, int, int, int] | None], options: MatchOptions,
                scheduler: Any, say: Callable[[str], None]
                ) -> tuple[list[int], list[PairMatches | None], list[str | None],
                           list[tuple[np.ndarray, np.ndarray]]]:
    """The keypoint and pair tasks of a block on ``scheduler``: each image's number of
    keypoints (0 where ``windows`` is None), the pairs' results (None where a pair failed),
    why each failed (None where it did not) and the positions of B's keypoints of each
    pair's kept matches, in the order of ``images`` and ``pairs``."""
    import uuid

    import dask

    delayed = dask.delayed
    run = uuid.uuid4().hex[:12]  # keys unique to this run (a cluster may run others)
    kps: dict[int, Any] = {}
    tasks: dict[str, Any] = {}
    for k, (im, window) in enumerate(zip(images, windows, strict=True)):
        if window is None:
            continue
        kps[k] = delayed(_detect, pure=False)(im, window, options,
                                              dask_key_name=f"keypoints-{run}-{k}")
        tasks[f"count-{k}"] = delayed(_count, pure=False)(
            kps[k], dask_key_name=f"count-{run}-{k}")
    for p, ((i, j, lap), search) in enumerate(zip(pairs, searches, strict=True)):
        tasks[f"pair-{p}"] = delayed(_pair, pure=False)(
            images[i], kps[i], images[j], kps[j], dem, lap, search, options,
            dask_key_name=f"pair-{run}-{p}")
    finished = [0]

    def done(name: str, value: Any) -> None:
        if name.startswith("count-"):
            k = int(name.split("-")[1])
            say(f"  {images[k].id}: {value} keypoints")
        else:
            res, messages, failed, _ = value
            finished[0] += 1
            for m in messages:
                say(m)
            if res is None:
                i, j, _ = pairs[int(name.split("-")[1])]
                say(f"  [{finished[0]}/{len(pairs)}] {images[i].id} & {images[j].id}: "
                    f"failed: {failed}")
            else:
                say(f"  [{finished[0]}/{len(pairs)}] {res.summary()}")

    out = run_tasks(tasks, scheduler, done)
    counts = [int(out.get(f"count-{k}", 0)) for k in range(len(images))]
    results = [out[f"pair-{p}"][0] for p in range(len(pairs))]
    failures = [out[f"pair-{p}"][2] for p in range(len(pairs))]
    positions_b = [out[f"pair-{p}"][3] for p in range(len(pairs))]
    return counts, results, failures, positions_b


def refine_links(images: Sequence[MatchImage], dem: DemSource,
                 jobs: Sequence[tuple[int, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
                 options: MatchOptions, scheduler: Any
                 ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The link tasks: ``(i, j, row_a, col_a, row_b, col_b)`` each, in order."""
    import uuid

    import dask

    if not jobs:
        return []
    run = uuid.uuid4().hex[:12]
    tasks = {f"link-{q}": dask.delayed(_link, pure=False)(
        images[i], images[j], dem, ra, ca, rb, cb, options, dask_key_name=f"link-{run}-{q}")
        for q, (i, j, ra, ca, rb, cb) in enumerate(jobs)}
    out = run_tasks(tasks, scheduler)
    return [out[f"link-{q}"] for q in range(len(jobs))]
