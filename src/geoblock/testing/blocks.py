"""Synthetic blocks of affine cameras with known truth, for tests and benchmarks.

:func:`affine_block` tiles ``grid[0] x grid[1]`` images over smooth terrain with a chosen
overlap, so that tie points are seen by two to four images. Each image has a true
:class:`~geoblock.testing.synthetic.AffineCamera` and an "on-board" camera that differs from
it by an affine image-space error (a shift of tens of pixels, a small rotation and scale),
which an order-1 :class:`~geoblock.models.ImageCorrection` (RPCV-1) represents exactly: the
adjusted block can reach the truth, and any error left is the estimator's. The measurements
carry Gaussian pointing noise, the GCPs survey noise, and optionally blunders.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from geoblock import coords
from geoblock.adjust.block import Block
from geoblock.adjust.observations import GroundPoints, ImagePoints
from geoblock.dem.grid import GridDem
from geoblock.models.corrections import ImageCorrection
from geoblock.models.protocol import SensorModel
from geoblock.testing.synthetic import AffineCamera

__all__ = ["SyntheticBlock", "affine_block"]


@dataclass(frozen=True, eq=False)
class SyntheticBlock:
    """A synthetic block and its truth.

    Attributes
    ----------
    block : Block
        On-board models wrapped in order-1 corrections, the measurements, GCPs/ICPs and DEM.
    true_models, onboard_models : dict of str to AffineCamera
    blunder : ndarray of bool, (M,)
        Which of ``block.measurements`` carry a blunder.
    truth_lon, truth_lat, truth_h : dict of str to float arrays
        True ground coordinates by point id (``point_index`` maps ids to rows).
    """

    block: Block
    true_models: dict[str, AffineCamera]
    onboard_models: dict[str, AffineCamera]
    blunder: np.ndarray
    point_id: np.ndarray
    truth_lon: np.ndarray
    truth_lat: np.ndarray
    truth_h: np.ndarray


def _terrain(frame: coords.LocalFrame, extent_m: float, relief_m: float, spacing_m: float,
             rng: np.random.Generator) -> tuple[GridDem, Callable[..., np.ndarray]]:
    """Smooth sinusoidal terrain over a square of ``extent_m`` around the frame origin, as a
    lon/lat GridDem of ellipsoidal heights, and the exact height function of (e, n)."""
    k = rng.uniform(1.0, 3.0, size=(3, 2)) * 2 * math.pi / extent_m
    ph = rng.uniform(0, 2 * math.pi, size=3)

    def height(e: np.ndarray, n: np.ndarray) -> np.ndarray:
        z = sum(np.sin(k[i, 0] * e + k[i, 1] * n + ph[i]) for i in range(3))
        return frame.h0 + 0.5 * relief_m * (1 + z / 3)

    half = 0.6 * extent_m
    deg_n = half / 111_000.0
    deg_e = half / (111_000.0 * math.cos(math.radians(frame.lat0)))
    n_post = int(math.ceil(2 * half / spacing_m)) + 1
    lon = np.linspace(frame.lon0 - deg_e, frame.lon0 + deg_e, n_post)
    lat = np.linspace(frame.lat0 + deg_n, frame.lat0 - deg_n, n_post)
    lon2, lat2 = np.meshgrid(lon, lat)
    e, n, _ = frame.from_geodetic(lon2, lat2, frame.h0)
    heights = height(e, n)
    dlon, dlat = lon[1] - lon[0], lat[1] - lat[0]
    transform = (dlon, 0.0, lon[0] - dlon / 2, 0.0, dlat, lat[0] - dlat / 2)
    return GridDem(heights, transform, "EPSG:4326"), height


def affine_block(
    grid: tuple[int, int] = (2, 3),
    *,
    shape: tuple[int, int] = (1000, 1000),
    gsd_m: float = 2.0,
    overlap: float = 0.3,
    gcps: int = 6,
    icps: int = 10,
    tps: int = 200,
    ictps: int = 20,
    sigma_px: float = 0.5,
    sigma_ground_m: float = 0.5,
    relief_m: float = 800.0,
    offnadir_deg: float = 10.0,
    error_px: float = 30.0,
    error_affine: float = 2e-3,
    blunder_fraction: float = 0.0,
    blunder_px: tuple[float, float] = (10.0, 50.0),
    seed: int = 0,
    dem_sigma_m: float = 2.0,
    wrap: Callable[[SensorModel], SensorModel] | None = None,
) -> SyntheticBlock:
    """A synthetic block of affine cameras (module docstring).

    Parameters
    ----------
    grid : (int, int)
        Images along north and east.
    shape : (int, int)
        Pixels per image.
    gsd_m : float
        Ground sampling distance, metres.
    overlap : float
        Fraction of an image shared with its neighbour, along each axis.
    gcps, icps : int
        Per image.
    tps, ictps : int
        In the whole block (each seen by at least two images).
    sigma_px : float
        Pointing noise, pixels.
    sigma_ground_m : float
        Survey noise of GCPs and ICPs, metres.
    relief_m : float
        Terrain relief, metres.
    offnadir_deg : float
        Largest view angle: each image looks in a random direction up to this angle.
    error_px, error_affine : float
        Standard deviations of the on-board error: shift (pixels) and the affine part
        (dimensionless; ``error_affine * size`` pixels at the image border).
    blunder_fraction : float
        Fraction of the TP measurements with a blunder of ``blunder_px`` pixels in a random
        direction.
    seed : int
    dem_sigma_m : float
        The DEM's stated accuracy, metres (the DEM itself is the true terrain).
    wrap : callable, optional
        Applied to each on-board camera before it is wrapped in the order-1
        ``ImageCorrection`` of ``block.models`` (e.g. a function fitting an RPC to it, to
        make a block of RPC images). ``onboard_models`` and ``true_models`` stay the
        affine cameras; the measurements, ground points and DEM do not depend on it.
    """
    rng = np.random.default_rng(seed)
    rows, cols = shape
    size_n, size_e = rows * gsd_m, cols * gsd_m
    step_n, step_e = size_n * (1 - overlap), size_e * (1 - overlap)
    frame = coords.LocalFrame(7.0, 44.0, 200.0)
    extent = max(grid[0] * step_n + size_n, grid[1] * step_e + size_e)
    dem, height = _terrain(frame, extent, relief_m, gsd_m * 20, rng)
    true_models, onboard = {}, {}
    centres = {}
    for a in range(grid[0]):
        for b in range(grid[1]):
            image = f"img{a}{b}"
            ce = (b - (grid[1] - 1) / 2) * step_e
            cn = ((grid[0] - 1) / 2 - a) * step_n
            lon0, lat0, _ = frame.to_geodetic(ce, cn, 0.0)
            h0 = float(height(ce, cn))
            tilt = np.radians(offnadir_deg) * rng.uniform(-1, 1, 2)
            coef = np.array([[(rows - 1) / 2, 0.0, -1 / gsd_m, math.tan(tilt[0]) / gsd_m],
                             [(cols - 1) / 2, 1 / gsd_m, 0.0, math.tan(tilt[1]) / gsd_m]])
            model = AffineCamera(shape, (float(lon0), float(lat0), h0), coef,
                                 (frame.h0 - 500, frame.h0 + relief_m + 500))
            true_models[image] = model
            # on-board: true = A onboard + a  ->  onboard = A^-1 (true - a)
            big = np.eye(2) + error_affine * rng.normal(size=(2, 2))
            shift = error_px * rng.normal(size=2)
            centre = np.array([(rows - 1) / 2, (cols - 1) / 2])
            # about the image centre: true - c = A (onboard - c) + a
            inv = np.linalg.inv(big)
            c_on = inv @ (coef - np.outer(centre + shift, [1, 0, 0, 0]))
            c_on[:, 0] += centre
            onboard[image] = AffineCamera(shape, model._origin, c_on, model.height_range)
            centres[image] = (ce, cn)
    images = list(true_models)

    def measure(e: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, ...]:
        """Project ground points into every image: (M,) point index, image, row, col."""
        lon, lat, h = frame.to_geodetic(e, n, 0.0)
        h = height(e, n)
        idx, img, rr, cc = [], [], [], []
        for image, model in true_models.items():
            r, c = model.project(lon, lat, h)
            inside = (r > 5) & (r < rows - 6) & (c > 5) & (c < cols - 6)
            k = np.flatnonzero(inside)
            idx.append(k)
            img.append(np.full(k.size, image))
            rr.append(r[k])
            cc.append(c[k])
        return (np.asarray(lon), np.asarray(lat), np.asarray(h), np.concatenate(idx),
                np.concatenate(img), np.concatenate(rr), np.concatenate(cc))

    ids, kinds = [], []
    pt_lon, pt_lat, pt_h = [], [], []
    m_id: list[str] = []
    m_img: list[str] = []
    m_row: list[float] = []
    m_col: list[float] = []
    m_kind: list[str] = []
    counter = 0

    def add(kind: str, e: np.ndarray, n: np.ndarray, min_images: int, want: int) -> None:
        nonlocal counter
        lon, lat, h, idx, img, r, c = measure(e, n)
        seen = np.bincount(idx, minlength=e.size)
        keep = np.flatnonzero(seen >= min_images)[:want]
        new_id = {}
        for k in keep:
            counter += 1
            new_id[k] = f"{kind}{counter:05d}"
            ids.append(new_id[k])
            kinds.append(kind)
            pt_lon.append(lon[k])
            pt_lat.append(lat[k])
            pt_h.append(h[k])
        sel = np.isin(idx, keep)
        m_id.extend(new_id[k] for k in idx[sel])
        m_img.extend(img[sel])
        m_row.extend(r[sel])
        m_col.extend(c[sel])
        m_kind.extend([kind] * int(sel.sum()))

    for image in images:
        ce, cn = centres[image]
        for kind, count in (("gcp", gcps), ("icp", icps)):
            e = ce + rng.uniform(-0.45, 0.45, count) * size_e
            n = cn + rng.uniform(-0.45, 0.45, count) * size_n
            add(kind, e, n, 1, count)
    half_e = (grid[1] - 1) * step_e / 2 + size_e / 2
    half_n = (grid[0] - 1) * step_n / 2 + size_n / 2
    for kind, count in (("tp", tps), ("ictp", ictps)):
        e = rng.uniform(-half_e, half_e, 20 * count + 100)
        n = rng.uniform(-half_n, half_n, 20 * count + 100)
        add(kind, e, n, 2, count)

    measured_id = np.array(m_id)
    measured_kind = np.array(m_kind)
    row = np.array(m_row) + sigma_px * rng.normal(size=len(m_row))
    col = np.array(m_col) + sigma_px * rng.normal(size=len(m_col))
    blunder = np.zeros(row.size, bool)
    if blunder_fraction > 0:
        tp = np.flatnonzero(measured_kind == "tp")
        pick = rng.choice(tp, size=int(round(blunder_fraction * tp.size)), replace=False)
        size = rng.uniform(*blunder_px, pick.size)
        angle = rng.uniform(0, 2 * np.pi, pick.size)
        row[pick] += size * np.sin(angle)
        col[pick] += size * np.cos(angle)
        blunder[pick] = True
    ids_a = np.array(ids)
    kinds_a = np.array(kinds)
    ground_sel = np.isin(kinds_a, ("gcp", "icp"))
    lon_a, lat_a, h_a = np.array(pt_lon), np.array(pt_lat), np.array(pt_h)
    g = ground_sel.sum()
    noise = sigma_ground_m * rng.normal(size=(g, 3))
    e0, n0, u0 = frame.from_geodetic(lon_a[ground_sel], lat_a[ground_sel], h_a[ground_sel])
    glon, glat, gh = frame.to_geodetic(e0 + noise[:, 0], n0 + noise[:, 1], u0 + noise[:, 2])
    ground = GroundPoints(ids_a[ground_sel], kinds_a[ground_sel], glon, glat, gh,
                          sigma_ground_m, sigma_ground_m, sigma_ground_m)
    meas = ImagePoints(measured_id, np.array(m_img), row, col, sigma_px, sigma_px,
                       measured_kind)
    models = {i: ImageCorrection(m if wrap is None else wrap(m), order=1)
              for i, m in onboard.items()}
    block = Block(models, meas, ground, dem, dem_sigma_m)
    return SyntheticBlock(block, true_models, onboard, blunder, ids_a, lon_a, lat_a, h_a)
