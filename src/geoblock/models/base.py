"""SensorModelBase: what sensor-model implementers subclass.

An implementer writes the model's state, its parameters and **one** natural direction as a
kernel on flat, finite float64 arrays:

* ``ground_to_image(lon, lat, h) -> (row, col[, status])`` (RPCs, affine cameras), or
* ``image_to_ground(row, col, h) -> (lon, lat[, status])`` (pushbroom line-of-sight models),

and the base class supplies the rest: broadcasting, NaN isolation and per-point status, the
other direction by Newton iteration, numeric ground and parameter partials, lines of sight,
footprints, equality, pickling and dask tokens derived from ``to_dict()``.
"""

from __future__ import annotations

import abc
import json
import warnings
from collections.abc import Callable, Collection, Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Self, TypeAlias

import numpy as np
from numpy.typing import NDArray

from geoblock import coords
from geoblock._array import broadcast_float64, warn_status
from geoblock.errors import GeoblockError, ModelFormatError, ParameterSetError
from geoblock.models.parameters import ParameterSet
from geoblock.pixels import image_domain
from geoblock.typing import (
    ArrayLike,
    EcefCoords,
    Float64Array,
    GroundCoords,
    ImageCoords,
    LineOfSight,
    Status,
)

if TYPE_CHECKING:
    from geoblock.models.protocol import SensorModel

__all__ = ["SensorModelBase", "canonical_json", "image_outline", "image_shape"]

_CONVERGED = np.uint8(Status.CONVERGED)

KernelResult: TypeAlias = (
    tuple[Float64Array, Float64Array] | tuple[Float64Array, Float64Array, NDArray[Any]]
)
"""What a kernel returns: ``(a, b)`` or ``(a, b, status)``, each ``(N,)`` (status: integer
:class:`~geoblock.typing.Status` codes)."""
Kernel = Callable[[Float64Array, Float64Array, Float64Array], KernelResult]


def canonical_json(data: Mapping[str, Any]) -> str:
    """The canonical JSON text of a model dictionary (sorted keys, no spaces)."""
    return json.dumps(data, sort_keys=True, separators=(",", ":"))


def image_outline(model: SensorModel, h: float, n: int = 32) -> GroundCoords:
    """The image outline of any model of the protocol backprojected at height ``h``.

    Parameters
    ----------
    model : SensorModel
    h : float
        Metres above the ellipsoid.
    n : int
        Points per side.

    Returns
    -------
    GroundCoords
        ``(4 n,)`` points along the pixel *edges* (:func:`geoblock.pixels.image_domain`: row
        and col from -0.5 to size - 0.5), clockwise in image space from the top-left corner,
        not closed; NaN where the model does not backproject.
    """
    r0, c0, r1, c1 = image_domain(model.shape)
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    row = np.concatenate([np.full(n, r0), r0 + (r1 - r0) * t, np.full(n, r1), r1 - (r1 - r0) * t])
    col = np.concatenate([c0 + (c1 - c0) * t, np.full(n, c1), c1 - (c1 - c0) * t, np.full(n, c0)])
    return model.backproject(row, col, np.full(row.shape, float(h)))


def image_shape(value: Any, where: str, *, maximum: int = 10**7) -> tuple[int, int]:
    """``(rows, cols)`` of an image, checked: two whole numbers of pixels from 1 to ``maximum``.

    ``value`` is read once (a generator is fine). Each item may be an integer, a float or
    numeric text (``"2920"``, ``"2920.0"``) holding a whole number; booleans, fractions,
    non-finite numbers and values outside ``1..maximum`` are refused.

    Parameters
    ----------
    value : iterable
        The two sizes, ``(rows, cols)``.
    where : str
        What the shape belongs to (a file, a file and its fields, a class); every message
        starts with it.
    maximum : int
        The largest size allowed per axis, pixels.

    Returns
    -------
    (int, int)

    Raises
    ------
    ModelFormatError
        ``value`` is not two sizes, or a size is not a whole number of pixels in
        ``1..maximum`` (the message names ``where``, the axis and the value).

    Examples
    --------
    >>> image_shape([2920, "4000.0"], "scene.json")
    (2920, 4000)
    """
    items: tuple[Any, ...] | None = None
    if not isinstance(value, str | bytes):
        try:
            items = tuple(value)
        except TypeError:
            items = None
    if items is None or len(items) != 2:
        raise ModelFormatError(
            f"{where}: image shape must be (rows, cols), two positive whole numbers of "
            f"pixels, got {value if items is None else items!r}"
        )
    sizes = []
    for axis, item in zip(("rows", "cols"), items, strict=True):
        size: int | None = None
        if isinstance(item, int | np.integer) and not isinstance(item, bool | np.bool_):
            size = int(item)
        elif not isinstance(item, bool | np.bool_):
            try:
                number = float(item.strip() if isinstance(item, str) else item)
            except (TypeError, ValueError, OverflowError):
                number = float("nan")
            if np.isfinite(number) and number == int(number):
                size = int(number)
        if size is None or not 1 <= size <= maximum:
            raise ModelFormatError(
                f"{where}: image {axis} {item!r} is not a whole number of pixels from 1 to "
                f"{maximum} (image sizes must be positive whole numbers of pixels; shape "
                f"{items!r})"
            )
        sizes.append(size)
    return sizes[0], sizes[1]


#: Kernel names before geoblock 0.2, mapped to their public names (with a DeprecationWarning).
_RENAMED_KERNELS = {
    "_ground_to_image": "ground_to_image",
    "_image_to_ground": "image_to_ground",
    "_ground_seed": "ground_seed",
}


class SensorModelBase(abc.ABC):
    """Base class for sensor models, with defaults derived from a few abstract members.

    Subclasses set ``name`` (the registry key, lowercase-kebab) and ``schema_version``, and
    implement ``shape``, ``height_range``, ``parameters``, ``with_parameters``, ``to_dict``,
    ``from_dict`` and at least one of ``ground_to_image`` / ``image_to_ground``. They may
    override ``partials_ground`` and ``partials_parameters`` with analytic versions, which the
    conformance kit (:mod:`geoblock.testing`) compares with the numeric defaults, and offer
    named parameter presets through ``parameter_sets`` and ``with_parameter_set`` (the
    default: ``"default"`` only, the parameters as they are).

    Models are immutable values: ``with_parameters`` returns a new model.
    """

    name: ClassVar[str]
    schema_version: ClassVar[int] = 1

    #: Newton iterations stop when the image-space correction is below this many pixels.
    newton_tolerance_px: ClassVar[float] = 1e-9
    #: A residual that no step can reduce (float64's floor) is accepted below this many pixels.
    newton_stall_px: ClassVar[float] = 1e-7
    #: Iteration cap of the Newton inversions.
    newton_max_iterations: ClassVar[int] = 30
    #: Largest number of points ``project``/``backproject`` hand to a kernel at once (bounds
    #: the memory of large calls of kernels with per-point temporaries); None: all at once.
    chunk_points: ClassVar[int | None] = None

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        for old, new in _RENAMED_KERNELS.items():  # the private names of geoblock 0.1
            if old in cls.__dict__ and new not in cls.__dict__:
                warnings.warn(
                    f"{cls.__qualname__}.{old} is deprecated: name the kernel {new} "
                    "(the public name since geoblock 0.2)",
                    DeprecationWarning,
                    stacklevel=3,  # the class statement (past ABCMeta.__new__)
                )
                setattr(cls, new, cls.__dict__[old])
        if getattr(cls, "__abstractmethods__", None):
            return
        if (
            cls.ground_to_image is SensorModelBase.ground_to_image
            and cls.image_to_ground is SensorModelBase.image_to_ground
        ):
            raise TypeError(
                f"{cls.__qualname__} must implement ground_to_image or image_to_ground "
                "(the other direction is derived by Newton iteration)"
            )

    # ---------------------------------------------------------------- abstract members
    @property
    @abc.abstractmethod
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the image, pixels."""

    @property
    @abc.abstractmethod
    def height_range(self) -> tuple[float, float]:
        """``(h_min, h_max)``: valid heights, metres above the WGS84 ellipsoid."""

    @property
    @abc.abstractmethod
    def parameters(self) -> ParameterSet:
        """The model's adjustable parameters."""

    @abc.abstractmethod
    def with_parameters(self, values: ArrayLike) -> Self:
        """A new model with parameter values ``values`` (P,); never mutates ``self``."""

    @abc.abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """JSON-safe state: ``{"model": name, "schema_version": n, ...}``."""

    @classmethod
    @abc.abstractmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        """Rebuild a model from :meth:`to_dict` output."""

    # ---------------------------------------------------------------- image ids
    @property
    def source_ids(self) -> Mapping[str, str]:
        """Ids of the image this model describes, by kind (optional; empty by default).

        Not part of the :class:`~geoblock.models.protocol.SensorModel` protocol: a model
        without this attribute, or with no ids, is never refused.
        :func:`geoblock.models.crop.model_for_image` compares them with the raster's ids
        (:attr:`ImageSource.source_ids <geoblock.io.images.ImageSource.source_ids>`) and
        refuses a mismatch of the same kind. Kinds: ``catalog_id`` (DigitalGlobe/Maxar
        ``CATID``), ``datastrip_id`` (Pleiades/SPOT 6-7 ``DS_...``), ``dataset_name`` (DIMAP
        ``DATASET_NAME``), ``nitf_iid2`` (NITF ``IID2``), ``ossim_image_id`` (OSSIM ``.geom``
        ``image_id``); a plugin may add its own kind (compared only with the same kind).
        """
        return {}

    # ---------------------------------------------------------------- parameter sets
    #: Names of the parameter presets :meth:`with_parameter_set` accepts; ``"default"`` (the
    #: parameters as the model has them) always among them. Subclasses with presets override
    #: it (a class attribute, or a property when the presets depend on the instance).
    parameter_sets: ClassVar[tuple[str, ...]] = ("default",)

    def with_parameter_set(self, name: str, **options: Any) -> Self:
        """A copy of the model whose ``parameters`` are the preset ``name``.

        A preset fixes which parameters an adjustment estimates and their a-priori sigmas
        (names, values, units, sigmas, adjustable mask): a block adjustment asks any model for
        ``"dg"`` or ``"mba"`` this way without knowing its class. ``"default"`` is accepted by
        every model and means the parameters as the model has them now.

        The base class knows ``"default"`` only (it returns ``self``). Subclasses with presets
        list them in :attr:`parameter_sets`, handle their names and options here and pass
        everything else on with ``super().with_parameter_set(name, **options)``.

        Parameters
        ----------
        name : str
            One of :attr:`parameter_sets`.
        **options
            Preset-specific options (``accuracy_m=`` for sets whose sigmas derive from a
            location accuracy); ``"default"`` takes none.

        Returns
        -------
        SensorModel
            A model of the same type and shape; ``self`` for ``"default"``.

        Raises
        ------
        ParameterSetError
            ``name`` is not one of :attr:`parameter_sets`, or an option is unknown to the set
            (the message names the model, the set and what it knows).
        """
        self._parameter_set_request(name, options)
        return self

    def _parameter_set_request(
        self, name: object, options: Mapping[str, Any], accepted: Collection[str] = ()
    ) -> None:
        """Refuse a ``with_parameter_set`` request whose name or options are unknown.

        Parameters
        ----------
        name : object
            The requested set; must be one of :attr:`parameter_sets`.
        options : mapping
            The options given.
        accepted : collection of str
            The options the set ``name`` accepts.

        Raises
        ------
        ParameterSetError
        """
        known = tuple(self.parameter_sets)
        label = f"{type(self).__qualname__} {getattr(self, 'name', '?')!r}"
        if not isinstance(name, str) or name not in known:
            raise ParameterSetError(
                f"{label} has no parameter set {name!r}; its parameter sets are {list(known)}"
            )
        unknown = sorted(set(options) - set(accepted))
        if unknown:
            takes = f"it accepts {sorted(accepted)}" if accepted else "it takes no options"
            raise ParameterSetError(
                f"{label}: parameter set {name!r} has no option(s) {unknown}; {takes}"
            )

    # ---------------------------------------------------------------- kernels
    def ground_to_image(self, lon: Float64Array, lat: Float64Array, h: Float64Array
                        ) -> KernelResult:
        """The ground -> image kernel an implementer writes (or inherits).

        Called by :meth:`project` with flat, finite, float64 arrays of one length ``(N,)``
        (NaN points and broadcasting are handled before); never call it with anything else.

        Parameters
        ----------
        lon, lat : ndarray, shape (N,)
            Geodetic longitude and latitude, degrees (WGS84).
        h : ndarray, shape (N,)
            Height above the WGS84 ellipsoid, metres.

        Returns
        -------
        tuple
            ``(row, col)`` or ``(row, col, status)``: image coordinates, pixels, pixel-centre
            convention (``(0, 0)`` is the centre of the first pixel), each ``(N,)``; ``status``
            an int8 array of :class:`~geoblock.typing.Status` codes (NaN row/col where not
            ``CONVERGED``). The default inverts :meth:`image_to_ground` by Newton iteration.
        """
        return self._newton_ground_to_image(lon, lat, h)

    def image_to_ground(self, row: Float64Array, col: Float64Array, h: Float64Array
                        ) -> KernelResult:
        """The image -> ground kernel an implementer writes (or inherits).

        Called by :meth:`backproject` with flat, finite, float64 arrays of one length ``(N,)``.

        Parameters
        ----------
        row, col : ndarray, shape (N,)
            Image coordinates, pixels, pixel-centre convention.
        h : ndarray, shape (N,)
            Height above the WGS84 ellipsoid at which the line of sight is cut, metres.

        Returns
        -------
        tuple
            ``(lon, lat)`` or ``(lon, lat, status)``: degrees, each ``(N,)``, with an int8
            :class:`~geoblock.typing.Status` array. The default inverts
            :meth:`ground_to_image` by Newton iteration (seeded by :meth:`ground_seed`).
        """
        return self._newton_image_to_ground(row, col, h)

    def ground_seed(self) -> tuple[float, float]:
        """``(lon, lat)`` of a ground point near the image centre, degrees.

        Needed only by models that implement ``ground_to_image`` alone, to start the Newton
        backprojection. The default backprojects nothing and so cannot know; such models
        override this (an RPC returns its LONG_OFF/LAT_OFF).
        """
        raise GeoblockError(
            f"{type(self).__qualname__} implements only ground_to_image: override "
            "ground_seed() to return a (lon, lat) near the image centre so that "
            "backproject can be derived"
        )

    # ---------------------------------------------------------------- public directions
    def project(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> ImageCoords:
        """Ground -> image.

        Parameters
        ----------
        lon, lat : array_like, (*S,)
            Degrees (WGS84).
        h : array_like, (*S,)
            Metres above the WGS84 ellipsoid.

        Returns
        -------
        ImageCoords
            ``row, col`` (*S,) in pixels (pixel-centre convention). Points that fail are NaN;
            one warning per failure kind gives the count. :meth:`project_with_status` returns
            the per-point status.
        """
        result, status = self.project_with_status(lon, lat, h)
        warn_status(status, f"{self.name}.project")
        return result

    def backproject(self, row: ArrayLike, col: ArrayLike, h: ArrayLike) -> GroundCoords:
        """Image -> ground on the surface at ellipsoidal height ``h``.

        Parameters
        ----------
        row, col : array_like, (*S,)
            Pixels, pixel-centre convention.
        h : array_like, (*S,)
            Metres above the WGS84 ellipsoid.

        Returns
        -------
        GroundCoords
            ``lon, lat`` degrees and ``h`` metres, (*S,). Failed points are NaN, with one
            warning per failure kind; :meth:`backproject_with_status` gives the status.
        """
        result, status = self.backproject_with_status(row, col, h)
        warn_status(status, f"{self.name}.backproject")
        return result

    def project_with_status(
        self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike
    ) -> tuple[ImageCoords, np.ndarray]:
        """:meth:`project` without warnings, with the (*S,) ``uint8`` :class:`Status` array."""
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
        row, col, status = self._apply(self.ground_to_image, "ground_to_image", lon, lat, h)
        return ImageCoords(row, col), status

    def backproject_with_status(
        self, row: ArrayLike, col: ArrayLike, h: ArrayLike
    ) -> tuple[GroundCoords, np.ndarray]:
        """:meth:`backproject` without warnings, with the (*S,) ``uint8`` :class:`Status` array."""
        row, col, h = broadcast_float64(row=row, col=col, h=h)
        lon, lat, status = self._apply(self.image_to_ground, "image_to_ground", row, col, h)
        h_out = np.where(status == _CONVERGED, h, np.nan)
        return GroundCoords(lon, lat, h_out), status

    def _apply(
        self, kernel: Kernel, kernel_name: str, a: np.ndarray, b: np.ndarray, c: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run a kernel on the finite points only; NaN and a status elsewhere."""
        shape = a.shape
        out_a = np.full(shape, np.nan)
        out_b = np.full(shape, np.nan)
        status = np.full(shape, np.uint8(Status.INVALID_INPUT), dtype=np.uint8)
        ok = np.isfinite(a) & np.isfinite(b) & np.isfinite(c)
        if ok.any():
            fa, fb, fc = a[ok], b[ok], c[ok]
            n = fa.shape[0]
            size = self.chunk_points
            if size is None or n <= size:
                ka, kb, ks = _unpack(kernel(fa, fb, fc), n, self, kernel_name)
            else:
                ka, kb = np.empty(n), np.empty(n)
                ks = np.empty(n, dtype=np.uint8)
                for start in range(0, n, size):
                    sl = slice(start, start + size)
                    ka[sl], kb[sl], ks[sl] = _unpack(kernel(fa[sl], fb[sl], fc[sl]),
                                                     fa[sl].shape[0], self, kernel_name)
            out_a[ok] = ka
            out_b[ok] = kb
            status[ok] = ks
        failed = status != _CONVERGED
        out_a[failed] = np.nan
        out_b[failed] = np.nan
        return out_a, out_b, status

    # ---------------------------------------------------------------- ECEF conveniences
    def project_ecef(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> ImageCoords:
        """Ground (ECEF metres) -> image."""
        return self.project(*coords.ecef_to_geodetic(x, y, z))

    def backproject_ecef(self, row: ArrayLike, col: ArrayLike, h: ArrayLike) -> EcefCoords:
        """Image -> ground at height ``h``, as ECEF metres."""
        return coords.geodetic_to_ecef(*self.backproject(row, col, h))

    # ---------------------------------------------------------------- partials
    #: Step of the numeric ground partials, metres along each local ENU axis.
    ground_partials_step_m: ClassVar[float] = 1.0

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """d(row, col)/d(x, y, z) ECEF at ground points, pixels per metre.

        The default uses central differences of ``ground_partials_step_m`` along local east,
        north and up, chained to ECEF.

        Returns
        -------
        ndarray, (*S, 2, 3)
            ``[..., 0, :]`` is d(row)/d(x, y, z), ``[..., 1, :]`` d(col)/d(x, y, z).
        """
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
        rot = coords.enu_rotation(lon, lat)  # (*S, 3, 3), rows e, n, u in ECEF
        xyz = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)  # (*S, 3)
        step = self.ground_partials_step_m
        # (2, 3, *S, 3): sign, ENU axis, points, ECEF component
        offsets = np.stack([rot, -rot])  # rot[..., k, :] is ENU axis k in ECEF
        offsets = np.moveaxis(offsets, -2, 1)  # (2, 3, *S, 3)
        shifted = xyz[None, None] + step * offsets
        g = coords.ecef_to_geodetic(shifted[..., 0], shifted[..., 1], shifted[..., 2])
        (row, col), _ = self.project_with_status(g.lon, g.lat, g.h)
        d_row = (row[0] - row[1]) / (2 * step)  # (3, *S) d row / d(e, n, u)
        d_col = (col[0] - col[1]) / (2 * step)
        j_enu = np.stack([np.moveaxis(d_row, 0, -1), np.moveaxis(d_col, 0, -1)], axis=-2)
        return j_enu @ rot  # (*S, 2, 3) @ (*S, 3, 3)

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """d(row, col)/d(parameter k) at ground points, pixels per unit of parameter k.

        The default uses central differences through :meth:`with_parameters` with a step of
        ``1e-3`` a-priori sigma (or ``1e-6 * max(1, |value|)`` for a free parameter). Every
        parameter has a column, fixed ones included.

        Returns
        -------
        ndarray, (*S, 2, P)
        """
        lon, lat, h = broadcast_float64(lon=lon, lat=lat, h=h)
        params = self.parameters
        out = np.empty(lon.shape + (2, len(params)))
        steps = parameter_steps(params)
        for k, step in enumerate(steps):
            cols = []
            for sign in (1.0, -1.0):
                values = np.array(params.values)
                values[k] += sign * step
                (r, c), _ = self.with_parameters(values).project_with_status(lon, lat, h)
                cols.append((r, c))
            out[..., 0, k] = (cols[0][0] - cols[1][0]) / (2 * step)
            out[..., 1, k] = (cols[0][1] - cols[1][1]) / (2 * step)
        return out

    def partials(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike
                 ) -> tuple[Float64Array, Float64Array]:
        """Both partials at once: ``(partials_ground(...), partials_parameters(...))``.

        The block adjustment asks for both at the same points; a model whose two partials
        share work (a line search solving each point, as a pushbroom's) overrides this to
        do that work once. The default calls the two methods.

        Returns
        -------
        ground : ndarray, (*S, 2, 3)
            d(row, col)/d(x, y, z) ECEF, pixels per metre.
        parameters : ndarray, (*S, 2, P)
            d(row, col)/d(parameter k), pixels per unit of parameter k.
        """
        return self.partials_ground(lon, lat, h), self.partials_parameters(lon, lat, h)

    # ---------------------------------------------------------------- geometry helpers
    def los(self, row: ArrayLike, col: ArrayLike) -> LineOfSight:
        """Lines of sight through image points, from the model's height range.

        Backprojects each point at both ends of ``height_range``.

        Returns
        -------
        LineOfSight
            ``origin`` (*S, 3) ECEF metres at the top of the height range and ``direction``
            (*S, 3) unit vectors pointing down.
        """
        row, col = broadcast_float64(row=row, col=col)
        h_min, h_max = self.height_range
        (lon, lat, h), _ = self.backproject_with_status(
            np.stack([row, row]), np.stack([col, col]),
            np.array([h_max, h_min]).reshape((2,) + (1,) * row.ndim),
        )
        xyz = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
        top, bottom = xyz[0], xyz[1]
        d = bottom - top
        with np.errstate(invalid="ignore", divide="ignore"):
            d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return LineOfSight(top, d)

    def footprint(self, h: float | None = None, n: int = 16) -> GroundCoords:
        """The image outline on the surface at height ``h``.

        Parameters
        ----------
        h : float, optional
            Metres above the ellipsoid; default the middle of ``height_range``.
        n : int
            Points per side.

        Returns
        -------
        GroundCoords
            (4 n,) points along the pixel *edges* (row and col from -0.5 to size - 0.5),
            clockwise in image space from the top-left corner, not closed.
        """
        if h is None:
            h = 0.5 * (self.height_range[0] + self.height_range[1])
        return image_outline(self, h, n)

    # ---------------------------------------------------------------- value semantics
    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return canonical_json(self.to_dict()) == canonical_json(other.to_dict())

    def __hash__(self) -> int:
        return hash(canonical_json(self.to_dict()))

    def __reduce__(self) -> tuple[Callable[[Mapping[str, Any]], Self], tuple[dict[str, Any]]]:
        return (type(self).from_dict, (self.to_dict(),))

    def __dask_tokenize__(self) -> tuple[str, str]:
        return (self.name, canonical_json(self.to_dict()))

    def __repr__(self) -> str:
        rows, cols = self.shape
        h0, h1 = self.height_range
        return (
            f"<{type(self).__name__} {self.name!r} {rows}x{cols} px, "
            f"h {h0:g}..{h1:g} m, {len(self.parameters)} parameters>"
        )

    # ---------------------------------------------------------------- Newton inversions
    def _newton_image_to_ground(self, row: Float64Array, col: Float64Array, h: Float64Array
                                ) -> KernelResult:
        """Backproject by Newton iteration on ``ground_to_image`` in (lon, lat).

        Start: a linearisation at ``ground_seed()``. Each iteration uses a forward-difference
        Jacobian (1e-6 degree steps) and halves a step that increases the residual (up to 8
        times). Converged when the image residual is below ``newton_tolerance_px``, or below
        ``newton_stall_px`` when no step reduces it any more (float64's floor); a point
        whose forward projection fails becomes DIVERGED, one that runs out of iterations
        MAX_ITERATIONS.
        """
        lon0, lat0 = self.ground_seed()
        n = row.shape[0]
        lon = np.full(n, float(lon0))
        lat = np.full(n, float(lat0))
        f0 = self._forward_flat(lon, lat, h)
        jac = self._jacobian_lonlat(lon, lat, h, f0)
        target = np.stack([row, col], axis=-1)
        delta = _solve2(jac, target - f0)
        lon = lon + delta[:, 0]
        lat = lat + delta[:, 1]
        return _newton(
            x=np.stack([lon, lat], axis=-1),
            residual=lambda x, idx: target[idx] - self._forward_flat(x[:, 0], x[:, 1], h[idx]),
            jacobian=lambda x, idx, f: self._jacobian_lonlat(
                x[:, 0], x[:, 1], h[idx], target[idx] - f
            ),
            residual_tol=self.newton_tolerance_px,
            step_tol=None,
            max_iter=self.newton_max_iterations,
            clamp=_clamp_lonlat,
            stall_tol=self.newton_stall_px,
        )

    def _newton_ground_to_image(self, lon: Float64Array, lat: Float64Array, h: Float64Array
                                ) -> KernelResult:
        """Project by Newton iteration on ``image_to_ground`` in (row, col).

        The residual is the ground miss in local metres (east, north); the Jacobian is a
        forward difference with 0.1-pixel steps; converged when the pixel step is below
        ``newton_tolerance_px``, or below ``newton_stall_px`` when no step reduces the ground
        miss any more (float64's floor).
        """
        rows, cols = self.shape
        n = lon.shape[0]
        x0 = np.tile([(rows - 1) / 2.0, (cols - 1) / 2.0], (n, 1))
        scale_e = np.radians(1.0) * coords.WGS84_A * np.cos(np.radians(lat))
        scale_n = np.radians(1.0) * coords.WGS84_A

        def residual(x: np.ndarray, idx: np.ndarray) -> np.ndarray:
            g_lon, g_lat = self._backward_flat(x[:, 0], x[:, 1], h[idx])
            d_lon = (lon[idx] - g_lon + 180.0) % 360.0 - 180.0
            return np.stack([d_lon * scale_e[idx], (lat[idx] - g_lat) * scale_n], axis=-1)

        def jacobian(x: np.ndarray, idx: np.ndarray, f: np.ndarray) -> np.ndarray:
            step = 0.1
            cols_ = []
            for k in range(2):
                xs = x.copy()
                xs[:, k] += step
                cols_.append((f - residual(xs, idx)) / step)  # d(ground)/d(image)
            return np.stack(cols_, axis=-1)

        return _newton(
            x=x0,
            residual=residual,
            jacobian=jacobian,
            residual_tol=None,
            step_tol=self.newton_tolerance_px,
            max_iter=self.newton_max_iterations,
            clamp=None,
            stall_tol=self.newton_stall_px,
        )

    def _forward_flat(self, lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> np.ndarray:
        """(N, 2) image coordinates from the ground->image kernel; NaN where it fails."""
        r, c, s = _unpack(
            self.ground_to_image(lon, lat, h), lon.shape[0], self, "ground_to_image"
        )
        out = np.stack([r, c], axis=-1)
        out[s != _CONVERGED] = np.nan
        return out

    def _backward_flat(self, row: Float64Array, col: Float64Array, h: Float64Array
                       ) -> tuple[Float64Array, Float64Array]:
        lo, la, s = _unpack(
            self.image_to_ground(row, col, h), row.shape[0], self, "image_to_ground"
        )
        bad = s != _CONVERGED
        lo = np.where(bad, np.nan, lo)
        la = np.where(bad, np.nan, la)
        return lo, la

    def _jacobian_lonlat(self, lon: Float64Array, lat: Float64Array, h: Float64Array,
                         f: Float64Array) -> Float64Array:
        """(N, 2, 2) d(row, col)/d(lon, lat) by forward differences of 1e-6 degree."""
        step = 1e-6
        j_lon = (self._forward_flat(lon + step, lat, h) - f) / step
        j_lat = (self._forward_flat(lon, lat + step, h) - f) / step
        return np.stack([j_lon, j_lat], axis=-1)


def parameter_steps(params: ParameterSet) -> np.ndarray:
    """Finite-difference steps for numeric parameter partials (see ``partials_parameters``)."""
    return np.where(
        np.isfinite(params.sigmas),
        1e-3 * params.sigmas,
        1e-6 * np.maximum(1.0, np.abs(params.values)),
    )


def _clamp_lonlat(x: np.ndarray) -> np.ndarray:
    x[:, 0] = (x[:, 0] + 180.0) % 360.0 - 180.0
    x[:, 1] = np.clip(x[:, 1], -90.0, 90.0)
    return x


def _unpack(result: object, n: int, model: object, kernel: str,
            ) -> tuple[Float64Array, Float64Array, NDArray[np.uint8]]:
    """Validate a kernel's ``(a, b[, status])`` result for ``n`` points."""
    if not isinstance(result, tuple) or len(result) not in (2, 3):
        raise GeoblockError(
            f"{type(model).__qualname__}.{kernel} must return (a, b) or (a, b, status), "
            f"got {type(result).__name__}"
        )
    a = np.asarray(result[0], dtype=np.float64)
    b = np.asarray(result[1], dtype=np.float64)
    if len(result) == 3 and result[2] is not None:
        s = np.asarray(result[2]).astype(np.uint8)
    else:
        s = np.full(n, _CONVERGED, dtype=np.uint8)
    for arr in (a, b, s):
        if arr.shape != (n,):
            raise GeoblockError(
                f"{type(model).__qualname__}.{kernel} returned shape {arr.shape} for {n} points"
            )
    s = np.where(
        (s == _CONVERGED) & ~(np.isfinite(a) & np.isfinite(b)), np.uint8(Status.DIVERGED), s
    )
    return a, b, s


def _solve2(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve (N, 2, 2) x = (N, 2); NaN for singular systems."""
    a, b, c, d = jac[:, 0, 0], jac[:, 0, 1], jac[:, 1, 0], jac[:, 1, 1]
    det = a * d - b * c
    with np.errstate(invalid="ignore", divide="ignore"):
        x0 = (d * rhs[:, 0] - b * rhs[:, 1]) / det
        x1 = (-c * rhs[:, 0] + a * rhs[:, 1]) / det
    return np.stack([x0, x1], axis=-1)


def _newton(
    *,
    x: np.ndarray,
    residual: Callable[[np.ndarray, np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    residual_tol: float | None,
    step_tol: float | None,
    max_iter: int,
    clamp: Callable[[np.ndarray], np.ndarray] | None,
    stall_tol: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised 2-D Newton with step halving, iterating only the points still active.

    ``residual(x, idx)`` is (N, 2) target minus model at the points ``idx``; ``jacobian(x, idx,
    f)`` is (N, 2, 2) d(model)/d(x) there. A point converges when its residual norm is at most
    ``residual_tol`` or its last step at most ``step_tol`` (whichever is given), or when no step
    reduces the residual any more while the residual (or, with ``step_tol``, the step) is below
    ``stall_tol``: float64's floor; it diverges
    when a residual or step is not finite. Returns ``(x0, x1, status)``, ``x`` updated in place.
    """
    status = np.full(x.shape[0], np.uint8(Status.MAX_ITERATIONS), dtype=np.uint8)
    active = np.arange(x.shape[0])
    f = residual(x, active)
    for iteration in range(max_iter + 1):
        norm = np.hypot(f[:, 0], f[:, 1])
        bad = ~np.isfinite(norm)
        status[active[bad]] = Status.DIVERGED
        keep = ~bad
        if residual_tol is not None:
            converged = keep & (norm <= residual_tol)
            status[active[converged]] = Status.CONVERGED
            keep &= ~converged
        active, f, norm = active[keep], f[keep], norm[keep]
        if active.size == 0 or iteration == max_iter:
            break
        xa = x[active]
        step = _solve2(jacobian(xa, active, f), f)
        singular = ~np.all(np.isfinite(step), axis=-1)
        status[active[singular]] = Status.DIVERGED
        ok = ~singular
        active, xa, f, norm, step = active[ok], xa[ok], f[ok], norm[ok], step[ok]
        scale = np.ones(active.size)
        x_new = xa + step
        if clamp is not None:
            x_new = clamp(x_new)
        f_new = residual(x_new, active)
        for _ in range(8):  # halve steps that make the residual grow
            worse = ~(np.hypot(f_new[:, 0], f_new[:, 1]) <= norm)
            if not worse.any():
                break
            scale[worse] *= 0.5
            x_try = xa[worse] + scale[worse, None] * step[worse]
            x_new[worse] = clamp(x_try) if clamp is not None else x_try
            f_new[worse] = residual(x_new[worse], active[worse])
        finished = np.zeros(active.size, bool)
        if stall_tol is not None:
            # float64's floor: no step reduces the residual any more
            size = norm if residual_tol is not None else np.max(np.abs(step), axis=-1)
            stalled = ~(np.hypot(f_new[:, 0], f_new[:, 1]) < norm) & (size <= stall_tol)
            status[active[stalled]] = Status.CONVERGED
            x_new[stalled] = xa[stalled]
            finished |= stalled
        if step_tol is not None:
            small = (np.max(np.abs(step), axis=-1) <= step_tol) & (scale == 1.0)
            small &= np.all(np.isfinite(f_new), axis=-1) & ~finished
            status[active[small]] = Status.CONVERGED
            finished |= small
        x[active] = x_new
        active, f = active[~finished], f_new[~finished]
    return x[:, 0], x[:, 1], status
