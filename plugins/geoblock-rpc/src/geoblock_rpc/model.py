"""RpcModel: the ``rpc`` sensor model (vendor RPC00B), evaluated as GDAL does."""

from __future__ import annotations

import math
import sys
import threading
from collections.abc import Mapping
from typing import Any, ClassVar, Self

import numpy as np

from geoblock import GroundCoords, ImageCoords, ParameterSet, SensorModelBase, coords
from geoblock.errors import ModelFormatError, SerializationError
from geoblock.models import broadcast_float64, image_shape
from geoblock.typing import ArrayLike, Float64Array
from geoblock_rpc import _params, _small
from geoblock_rpc.rpc00b import MAX_PIXELS, Rpc00b

__all__ = ["RpcModel"]


#: default of ``RpcModel(height_margin_m=...)``: metres of height accepted beyond the vendor's
#: range HEIGHT_OFF -/+ HEIGHT_SCALE (see the class docstring for the measurement behind it)
HEIGHT_MARGIN_M = 1500.0

#: batches smaller than this run on the calling thread (numba's pool has a launch cost)
PARALLEL_MIN_POINTS = 32768


#: batches of at most this many points are projected in numpy (:mod:`geoblock_rpc._small`, the
#: compiled kernel's bits) while the process has not imported numba: 65536 points take 12 ms in
#: numpy (16 MB of temporaries), a process's first kernel call 0.28 s (numba's import and
#: registries; 0.5 s more per whole process, benchmarks/README.md, Start-up)
SMALL_BATCH_MAX = 65536

#: points a process projects in numpy in all before it loads the kernels anyway: ~0.2 s of
#: numpy (190 ns per point against 7 in the warm kernel), less than the kernels' start-up it
#: saves, so a process of many small batches pays at most about twice the start-up (rent or
#: buy)
SMALL_BUDGET_POINTS = 1 << 20

#: what a localised point costs in numpy, in projected points (for the two limits above)
LOCALISE_COST = 4

_small_points = 0  # points projected in numpy so far (races between threads only blur it)


def _use_numpy(n: int) -> bool:
    """Whether a batch costing ``n`` projected points in numpy (a projection of ``n`` points,
    a localisation of ``n / LOCALISE_COST``) runs in numpy rather than the compiled kernel.

    Both give the same bits (tested), so the choice changes speed only: numpy for small
    batches while numba is not imported (:data:`SMALL_BATCH_MAX`, :data:`SMALL_BUDGET_POINTS`),
    the kernel once it is (its start-up is then mostly paid, and it is 20-30x faster at every
    size).
    """
    global _small_points
    if n > SMALL_BATCH_MAX or "numba" in sys.modules:
        return False
    if _small_points + n > SMALL_BUDGET_POINTS:
        return False
    _small_points += n
    return True


def parallel_ok(n: int) -> bool:
    """Whether a batch of ``n`` points uses the parallel kernels: large batches on the main
    thread only. Worker threads (dask tasks) already run in parallel, and numba's default
    thread pool must not be entered from several threads at once."""
    return n >= PARALLEL_MIN_POINTS and threading.current_thread() is threading.main_thread()


def _flat(*arrays: ArrayLike, names: tuple[str, ...]) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """The broadcast shape and flat contiguous float64 views (copies only when needed).

    The kernels never write their inputs, so float64 arrays of one shape pass without a copy
    (24 MB saved per 10^6 points); anything else goes through the core's broadcasting, with
    its error messages, and only what is not already a contiguous float64 array of the
    broadcast shape is copied.
    """
    try:
        arrs = [np.asarray(a, dtype=np.float64) for a in arrays]
    except (TypeError, ValueError):
        arrs = []
    if arrs and all(a.shape == arrs[0].shape for a in arrs):
        return arrs[0].shape, [np.ascontiguousarray(a).ravel() for a in arrs]
    out = broadcast_float64(_copy=False, **dict(zip(names, arrays, strict=True)))
    return out[0].shape, [np.ascontiguousarray(a).ravel() for a in out]


def _out_arrays(
    out: Any, shape: tuple[int, ...], inputs: list[np.ndarray], names: tuple[str, ...]
) -> list[np.ndarray]:
    """Check an ``out=`` argument: one array per name, float64 but the last (``status``, uint8),
    C-contiguous, writeable, of ``shape``, overlapping neither each other nor the inputs."""
    if not isinstance(out, tuple | list) or len(out) != len(names):
        got = f"{len(out)} items" if isinstance(out, tuple | list) else type(out).__name__
        raise ValueError(f"out must be {len(names)} arrays ({', '.join(names)}), got {got}")
    for i, (a, name) in enumerate(zip(out, names, strict=True)):
        dtype = np.dtype(np.uint8 if i == len(names) - 1 else np.float64)
        if not isinstance(a, np.ndarray):
            raise ValueError(f"out[{i}] ({name}) must be a numpy array, got {type(a).__name__}")
        if a.dtype != dtype or a.shape != shape:
            raise ValueError(f"out[{i}] ({name}) must be a {dtype} array of shape {shape} (the "
                             f"broadcast shape of the inputs), got {a.dtype} {a.shape}")
        if not (a.flags.c_contiguous and a.flags.writeable):
            raise ValueError(f"out[{i}] ({name}) must be C-contiguous and writeable")
        for j in range(i):
            if np.may_share_memory(a, out[j]):
                raise ValueError(f"out[{i}] ({name}) overlaps out[{j}] ({names[j]})")
        if any(np.may_share_memory(a, x) for x in inputs):
            raise ValueError(f"out[{i}] ({name}) overlaps an input array")
    return list(out)


class RpcModel(SensorModelBase):
    """A vendor RPC00B model.

    Parameters
    ----------
    rpc : Rpc00b
        The coefficients (pixel-centre convention).
    shape : (int, int), optional
        ``(rows, cols)`` of the image. Files that do not state it (most RPC text formats, a
        DIMAP ``RPC_*.XML`` without its ``DIM_*.XML``) get ``ceil(OFF + SCALE + 0.5)`` per
        axis: the extent the RPC was fitted over, which is not the image's size
        (:attr:`shape_stated` is then False).
    domain_limit : float
        Horizontal validity domain: points whose normalised ``L`` or ``P`` exceed this
        magnitude (RPC00B is fitted on [-1, 1]; GDAL flags above 1.5), or that lie farther
        than ``(domain_limit - 1) / 2`` of the box size outside MIN/MAX_LONG/LAT when the file
        gives that box, get status OUT_OF_DOMAIN and NaN.
    height_limit : float
        Vertical validity domain in normalised height: heights within
        ``HEIGHT_OFF +/- height_limit * |HEIGHT_SCALE|`` are accepted (and those within
        ``height_margin_m`` of the vendor's range, whichever is wider:
        :attr:`valid_height_range`).
    height_margin_m : float
        Vertical validity domain in metres: heights up to this far outside the vendor's range
        ``HEIGHT_OFF -/+ |HEIGHT_SCALE|`` are accepted (default :data:`HEIGHT_MARGIN_M`, 1500 m).
        Vendors fit the RPC over the heights of the scene's own terrain model, often a narrow
        range (490-660 m for shareloc's ``PHRDIMAP_P1BP--2018122638935449CP``, 26 m for GDAL's
        test_transformer_11), while terrain at the scene's edges or a finer DEM goes a few
        hundred metres beyond; a line of sight is straight, so the height terms extrapolate
        gently: that RPC stays within 0.016 px (max) of CNES's physical location grid at -30 m,
        0.017 px at 1202 m, 0.15 px at 2435 m and 0.92 px at 4900 m. A limit in normalised
        height alone refused its 125 m (``H = -5.3``), which shareloc and GDAL localise. GDAL
        checks no height domain at all.
    source_ids : mapping of str to str, optional
        Ids of the image the file describes, by kind (:attr:`SensorModelBase.source_ids
        <geoblock.models.base.SensorModelBase.source_ids>`): ``ossim_image_id`` of an OSSIM
        ``.geom``, ``catalog_id`` of a DigitalGlobe ISD, a raster's own ids. Not serialised.

    Notes
    -----
    No adjustable parameters: refine an RPC with ``geoblock.ImageCorrection(model, order)``
    (RPCV-0: order 0, RPCV-1: order 1). ``ERR_BIAS``/``ERR_RAND`` are kept in
    :attr:`rpc` as the vendor's a-priori accuracy (metres); ``ERR_BIAS`` is also the model's
    :attr:`location_accuracy_m`, as linescan models state theirs.
    """

    name: ClassVar[str] = "rpc"
    schema_version: ClassVar[int] = 1

    #: localisation: tolerance and float64-floor acceptance (pixels), iteration cap
    localisation_tolerance_px: ClassVar[float] = 1e-8
    localisation_stall_px: ClassVar[float] = 1e-6
    localisation_max_iterations: ClassVar[int] = 30

    def __init__(
        self,
        rpc: Rpc00b,
        shape: tuple[int, int] | None = None,
        *,
        domain_limit: float = 1.5,
        height_limit: float = 5.0,
        height_margin_m: float = HEIGHT_MARGIN_M,
        source_ids: Mapping[str, str] | None = None,
    ) -> None:
        self._source_ids = dict(source_ids or {})
        if not isinstance(rpc, Rpc00b):
            raise TypeError(f"RpcModel needs an Rpc00b, got {type(rpc).__name__}")
        rpc.check_plausible()
        self._rpc = rpc
        self._shape_stated = shape is not None
        if shape is None:
            shape = (
                max(1, math.ceil(rpc.line_off + abs(rpc.line_scale) + 0.5)),
                max(1, math.ceil(rpc.samp_off + abs(rpc.samp_scale) + 0.5)),
            )
        self._shape = image_shape(shape, rpc.source, maximum=int(MAX_PIXELS))
        try:
            self._domain_limit = float(domain_limit)
            self._height_limit = float(height_limit)
        except (TypeError, ValueError):
            self._domain_limit = self._height_limit = math.nan
        try:
            self._height_margin_m = float(height_margin_m)
        except (TypeError, ValueError):
            self._height_margin_m = math.nan
        if not (1.0 <= self._domain_limit < math.inf and 1.0 <= self._height_limit < math.inf):
            raise ModelFormatError(
                f"{rpc.source}: RpcModel domain_limit and height_limit must be finite and >= 1, "
                f"got {domain_limit!r}, {height_limit!r}"
            )
        if not 0.0 <= self._height_margin_m < math.inf:
            raise ModelFormatError(f"{rpc.source}: RpcModel height_margin_m must be finite and "
                                   f">= 0 metres, got {height_margin_m!r}")
        box = (
            (rpc.min_long, rpc.max_long, rpc.min_lat, rpc.max_lat)
            if rpc.has_validity_box
            else None
        )
        # the kernels test |H| against one normalised limit: the wider of the two rules
        scale = abs(rpc.height_scale)
        vertical = max(self._height_limit, 1.0 + self._height_margin_m / scale)
        self._valid_heights = (rpc.height_off - vertical * scale,
                               rpc.height_off + vertical * scale)
        self._prm = _params.pack(rpc, self._domain_limit, vertical, box)
        self._coef = np.ascontiguousarray(rpc.coefficients)

    @classmethod
    def example(cls) -> Self:
        """A synthetic 10 000 x 12 000 px RPC near Nice, with cubic and height terms.

        Not a vendor model: small made-up distortions on a north-up, 0.5 m GSD geometry with
        10 degrees of parallax. For examples and tests that need no data files.
        """
        line_num = np.zeros(20)
        samp_num = np.zeros(20)
        line_den = np.zeros(20)
        samp_den = np.zeros(20)
        line_num[[2, 3, 1, 7, 11, 14]] = (-1.0, 0.05, 0.01, 2e-4, -1e-4, 3e-4)
        samp_num[[1, 3, 2, 8, 15, 12]] = (1.0, -0.02, -0.008, -3e-4, 1e-4, 2e-4)
        line_den[[0, 1, 2]] = (1.0, 1e-4, -2e-4)
        samp_den[[0, 1, 2, 3]] = (1.0, -1e-4, 1e-4, 5e-5)
        rpc = Rpc00b(
            line_off=4999.5, samp_off=5999.5, lat_off=43.70, long_off=7.05, height_off=500.0,
            line_scale=5000.0, samp_scale=6000.0, lat_scale=0.0225, long_scale=0.0373,
            height_scale=1000.0, line_num=line_num, line_den=line_den, samp_num=samp_num,
            samp_den=samp_den, err_bias=5.0, err_rand=0.5, source="RpcModel.example()",
        )
        return cls(rpc, (10000, 12000))

    # ------------------------------------------------------------------ state
    @property
    def rpc(self) -> Rpc00b:
        """The RPC00B coefficients."""
        return self._rpc

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def shape_stated(self) -> bool:
        """Whether :attr:`shape` is the image's size as a file (or the caller) stated it.

        False when the RPC file gives no image size: :attr:`shape` is then the RPC's fitted
        extent ``ceil(OFF + SCALE + 0.5)``, and
        :func:`~geoblock.models.crop.model_for_image` takes an image of about that size
        (within :data:`~geoblock.models.crop.UNSTATED_SHAPE_TOLERANCE`) as the whole scene.
        """
        return self._shape_stated

    @property
    def height_range(self) -> tuple[float, float]:
        """``HEIGHT_OFF -/+ HEIGHT_SCALE``, metres above the ellipsoid."""
        r = self._rpc
        return (r.height_off - abs(r.height_scale), r.height_off + abs(r.height_scale))

    @property
    def location_accuracy_m(self) -> float | None:
        """The product's stated location accuracy (1 sigma, metres), or None if unknown.

        RPC00B's ``ERR_BIAS`` (``errBias`` in a .RPB, ``ERR_BIAS`` in an _RPC.TXT): the RMS
        bias error per horizontal axis of all points of the image, metres; None when the file
        does not give it or gives -1 or 0 ("unknown"; OSSIM .geom files write 0). ``ERR_RAND``,
        the random error of each point (typically a few decimetres), stays in :attr:`rpc`.
        DIMAP v2's ``ERR_BIAS_ROW/COL`` and ``ERR_BIAS_X/Y`` are the residuals of the RFM's
        fit to the physical model (pixels, degrees), not a location accuracy: not used.
        ``geoblock match`` sizes its search window from it.
        """
        bias = self._rpc.err_bias
        return bias if bias is not None and bias > 0 else None

    @property
    def domain_limit(self) -> float:
        """Horizontal validity limit on the normalised L, P."""
        return self._domain_limit

    @property
    def height_limit(self) -> float:
        """Vertical validity limit on the normalised H (see also :attr:`height_margin_m`)."""
        return self._height_limit

    @property
    def height_margin_m(self) -> float:
        """Metres of height accepted beyond the vendor's range ``HEIGHT_OFF -/+ HEIGHT_SCALE``."""
        return self._height_margin_m

    @property
    def valid_height_range(self) -> tuple[float, float]:
        """``(lowest, highest)`` height (metres above the ellipsoid) the model answers at.

        The vendor's range widened by :attr:`height_margin_m` on each side, or
        ``HEIGHT_OFF -/+ height_limit * |HEIGHT_SCALE|`` when that is wider; a point outside
        gets OUT_OF_DOMAIN and NaN (projection and localisation alike).
        """
        return self._valid_heights

    @property
    def parameters(self) -> ParameterSet:
        return ParameterSet.empty()

    def with_parameters(self, values: ArrayLike) -> Self:
        self.parameters.with_values(values)  # refuses anything but an empty array
        return self

    def with_shape(self, shape: tuple[int, int]) -> Self:
        """The same RPC with another image shape."""
        return type(self)(self._rpc, shape, domain_limit=self._domain_limit,
                          height_limit=self._height_limit,
                          height_margin_m=self._height_margin_m, source_ids=self._source_ids)

    @property
    def source_ids(self) -> Mapping[str, str]:
        """Ids of the image the RPC was read for, by kind (empty when the file has none)."""
        return dict(self._source_ids)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "shape": list(self._shape),
            "shape_stated": self._shape_stated,
            "domain_limit": self._domain_limit,
            "height_limit": self._height_limit,
            "height_margin_m": self._height_margin_m,
            "rpc": self._rpc.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        try:
            rpc = Rpc00b.from_dict(data["rpc"], source="model dictionary")
            shape = tuple(data["shape"]) if data.get("shape_stated", True) else None
            return cls(rpc, shape, domain_limit=data.get("domain_limit", 1.5),
                       height_limit=data.get("height_limit", 5.0),
                       height_margin_m=data.get("height_margin_m", HEIGHT_MARGIN_M))
        except KeyError as exc:
            raise SerializationError(f"rpc model dictionary misses {exc}") from None
        except ModelFormatError as exc:  # the JSON reader names the file of a SerializationError
            raise SerializationError(str(exc)) from exc

    def ground_seed(self) -> tuple[float, float]:
        return self._rpc.long_off, self._rpc.lat_off

    # ------------------------------------------------------------------ directions
    def project_with_status(
        self,
        lon: ArrayLike,
        lat: ArrayLike,
        h: ArrayLike,
        *,
        out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> tuple[ImageCoords, np.ndarray]:
        """Ground -> image in one fused pass (NaN handling and status included).

        Large batches, and every batch once numba is imported, run the compiled kernel; small
        ones in a process without numba run its numpy twin (:mod:`geoblock_rpc._small`), which
        gives the same bits and spares a short command numba's 0.3-0.5 s of start-up.

        Parameters
        ----------
        lon, lat : array_like, (*S,)
            Degrees (WGS84); broadcast together with ``h``.
        h : array_like, (*S,)
            Metres above the WGS84 ellipsoid.
        out : (ndarray, ndarray, ndarray), optional
            ``(row, col, status)`` to write the results into instead of new arrays: C-contiguous,
            writeable arrays of the broadcast shape (*S,), ``row`` and ``col`` float64 (pixels),
            ``status`` uint8, none overlapping another or an input. Reusing them across calls
            saves the allocation and the page faults of fresh memory (30-40 % of a 10^6-point
            call). A wrong dtype, shape, layout or an overlap raises ValueError.

        Returns
        -------
        ImageCoords, ndarray
            ``row, col`` (*S,) float64, pixels (pixel-centre convention), NaN where a point
            fails, and the (*S,) uint8 :class:`~geoblock.Status`; with ``out``, the very arrays
            given.
        """
        shape, (x, y, z) = _flat(lon, lat, h, names=("lon", "lat", "h"))
        result: list[np.ndarray]
        if out is None:
            # fresh pages: the kernel's threads fault them in, each its share
            result = [np.empty(shape), np.empty(shape), np.empty(shape, np.uint8)]
        else:
            result = _out_arrays(out, shape, [x, y, z], ("row", "col", "status"))
        row, col, status = (a.reshape(-1) for a in result)
        if _use_numpy(x.size):
            _small.project(x, y, z, self._prm, self._coef, row, col, status)
        else:
            from geoblock_rpc import _kernels  # numba: 0.3-0.5 s on the first use in a process

            kernel = _kernels.project if parallel_ok(x.size) else _kernels.project_serial
            kernel(x, y, z, self._prm, self._coef, row, col, status)
        return ImageCoords(result[0], result[1]), result[2]

    def backproject_with_status(
        self,
        row: ArrayLike,
        col: ArrayLike,
        h: ArrayLike,
        *,
        out: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> tuple[GroundCoords, np.ndarray]:
        """Image -> ground at height h: Newton with the analytic Jacobian.

        Compiled (numba), or for a small batch in a process without numba its numpy twin, with
        the same bits (see :meth:`project_with_status`; up to 16384 points a call).

        Converged points meet ``localisation_tolerance_px`` (1e-8 px), or float64's floor
        below ``localisation_stall_px``; others get MAX_ITERATIONS, DIVERGED or
        OUT_OF_DOMAIN and NaN.

        Parameters
        ----------
        row, col : array_like, (*S,)
            Pixels (pixel-centre convention); broadcast together with ``h``.
        h : array_like, (*S,)
            Metres above the WGS84 ellipsoid.
        out : (ndarray, ndarray, ndarray, ndarray), optional
            ``(lon, lat, h, status)`` to write the results into instead of new arrays:
            C-contiguous, writeable arrays of the broadcast shape (*S,), ``lon`` and ``lat``
            float64 (degrees), ``h`` float64 (metres), ``status`` uint8, none overlapping
            another or an input. Reusing them across calls saves the allocation and the page
            faults of fresh memory (a few % of a 10^6-point call, and 25 MB of peak memory). A
            wrong dtype, shape, layout or an overlap raises ValueError.

        Returns
        -------
        GroundCoords, ndarray
            ``lon, lat`` (*S,) degrees and ``h`` (*S,) metres (the input height), NaN where a
            point fails, and the (*S,) uint8 :class:`~geoblock.Status`; with ``out``, the very
            arrays given.
        """
        shape, (r, c, z) = _flat(row, col, h, names=("row", "col", "h"))
        result: list[np.ndarray]
        if out is None:
            result = [np.empty(shape), np.empty(shape), z.reshape(shape).copy(),
                      np.empty(shape, np.uint8)]
        else:
            result = _out_arrays(out, shape, [r, c, z], ("lon", "lat", "h", "status"))
            np.copyto(result[2], z.reshape(shape))
        lon, lat, h_out, status = (a.reshape(-1) for a in result)
        args = (r, c, z, self._prm, self._coef, self.localisation_tolerance_px,
                self.localisation_stall_px, self.localisation_max_iterations, lon, lat, status)
        # numpy's Newton costs 4x its projection per point (0.6-0.8 us against 0.1 in the kernel)
        if _use_numpy(LOCALISE_COST * r.size):
            _small.localise(*args)
        else:
            from geoblock_rpc import _kernels

            kernel = _kernels.localise if parallel_ok(r.size) else _kernels.localise_serial
            kernel(*args)
        h_out[status != 0] = np.nan  # 5x faster than np.where(status == 0, z, np.nan)
        return GroundCoords(result[0], result[1], result[2]), result[3]

    def ground_to_image(self, lon, lat, h):
        (row, col), status = self.project_with_status(lon, lat, h)
        return row, col, status

    def image_to_ground(self, row, col, h):
        (lon, lat, _), status = self.backproject_with_status(row, col, h)
        return lon, lat, status

    # ------------------------------------------------------------------ partials
    def partials_geodetic(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Analytic d(row, col)/d(lon, lat, h): (*S, 2, 3), pixels per degree and per metre."""
        shape, (x, y, z) = _flat(lon, lat, h, names=("lon", "lat", "h"))
        out = np.empty((x.size, 2, 3))
        from geoblock_rpc import _kernels

        kernel = (_kernels.partials_geodetic if parallel_ok(x.size)
                  else _kernels.partials_geodetic_serial)
        kernel(x, y, z, self._prm, self._coef, out)
        return out.reshape(shape + (2, 3))

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """Analytic d(row, col)/d(x, y, z) ECEF: (*S, 2, 3), pixels per metre."""
        return self.partials_geodetic(lon, lat, h) @ coords.ecef_to_geodetic_jacobian(lon, lat, h)

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """No parameters: (*S, 2, 0). Wrap in ``ImageCorrection`` to refine."""
        shape = np.broadcast_shapes(np.shape(lon), np.shape(lat), np.shape(h))
        return np.zeros(shape + (2, 0))

    def __repr__(self) -> str:
        return (f"<RpcModel {self._shape[0]}x{self._shape[1]} px, "
                f"h {self.height_range[0]:g}..{self.height_range[1]:g} m, from {self._rpc.source}>")
