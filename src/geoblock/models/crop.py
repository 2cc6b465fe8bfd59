"""Crops of a scene: any sensor model, shifted to address a window of its image.

Vendors' metadata (RPCs, DIMAP, OSSIM ``.geom``...) describe the full scene; an image is often
a crop of it (a processing window, shareloc's 500 x 500 Ventoux crop of a 41801 x 39182
Pleiades scene). :class:`CroppedModel` wraps **any** model for a crop whose first pixel is
scene pixel ``(row0, col0)``: crop pixel ``(r, c)`` is scene pixel ``(r + row0, c + col0)``,
nothing else changes (a pure shift, exact, no resampling of the geometry).

:func:`model_for_image` reconciles an image with a model wherever the two meet (``geoblock
ortho``, ``geoblock localize --image``, block files): the crop offset comes from the caller
(``crop_offset=``) or from the raster itself (a pixel-unit geotransform: no CRS, pixel size 1,
origin at the crop's first pixel, as shareloc's crops carry and ``gdal_translate -srcwin``
keeps from such a source; read by
:func:`geoblock.io.open_image` into :attr:`ImageSource.crop_offset
<geoblock.io.images.ImageSource.crop_offset>`); an image whose shape differs from the
model's with no crop information is refused with both shapes and what to pass, never
silently placed at the scene's top-left.

One exception: a model whose file states no image size (``shape_stated`` False, e.g. an RPC
text file or a DIMAP ``RPC_*.XML`` copied without its ``DIM_*.XML``: its ``shape`` is then the
extent the vendor fitted the model over, not the image's) takes an image within
:data:`UNSTATED_SHAPE_TOLERANCE` of that extent on both axes as its whole scene.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, Self

from geoblock.errors import CropError, ModelFormatError, ModelImageMismatchError
from geoblock.models.base import KernelResult, SensorModelBase, image_shape
from geoblock.models.curves import CorrectionCurve
from geoblock.models.parameters import ParameterSet
from geoblock.models.protocol import SensorModel
from geoblock.typing import ArrayLike, Float64Array

__all__ = ["CropError", "CroppedModel", "model_for_image"]

#: How far (pixels) a crop may stick out of its scene (fractional offsets, rounding).
FIT_TOLERANCE_PX = 0.5

#: Relative difference per axis between an image's size and the fitted extent of a model that
#: states no image size (``shape_stated`` False) within which the image is taken as the whole
#: scene. Vendors fit an RPC over the image plus a margin: the fitted extent
#: ``ceil(OFF + SCALE + 0.5)`` differs from the image by 1.1 % (rows) and 0.07 % (columns) for
#: the Pleiades Ventoux scene (42248 x 39208 vs 41801 x 39182 px), and by 1.4 % to 3.6 % for
#: the WorldView-1/2 products of ../shared/data (their ISDs state both); a crop of less than
#: 90 % of the scene still needs its offset.
UNSTATED_SHAPE_TOLERANCE = 0.1


def _offset(value: Any, what: str = "offset") -> tuple[float, float]:
    try:
        row0, col0 = (float(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise CropError(f"CroppedModel: {what} must be (row0, col0), got {value!r}") from exc
    if not (math.isfinite(row0) and math.isfinite(col0)):
        raise CropError(f"CroppedModel: {what} must be finite, got {value!r}")
    return row0, col0


def _shape(value: Any) -> tuple[int, int]:
    try:
        return image_shape(value, "CroppedModel")
    except ModelFormatError as exc:
        raise CropError(str(exc)) from exc


def _fits(offset: tuple[float, float], shape: tuple[int, int],
          scene: tuple[int, int]) -> bool:
    """Whether a crop of ``shape`` at ``offset`` lies inside ``scene`` (to FIT_TOLERANCE_PX)."""
    tol = FIT_TOLERANCE_PX
    return all(-tol <= o and o + n <= s + tol
               for o, n, s in zip(offset, shape, scene, strict=True))


class CroppedModel(SensorModelBase):
    """Any sensor model restricted to a crop of its image: a pure image-space shift.

    Crop pixel ``(row, col)`` is pixel ``(row + row0, col + col0)`` of the wrapped model
    (pixel-centre convention on both sides); ground coordinates, height range, parameters and
    ground/parameter partials are the wrapped model's.

    Parameters
    ----------
    model : SensorModel
        The full scene's model (any registered model). A :class:`CroppedModel` is unwrapped:
        a crop of a crop is one crop with the offsets added.
    offset : (float, float)
        ``(row0, col0)``: the scene pixel of the crop's first pixel.
    shape : (int, int)
        ``(rows, cols)`` of the crop.

    Raises
    ------
    CropError
        ``offset`` is not two finite numbers, ``shape`` not two whole numbers of pixels, or
        the crop does not lie inside ``model``'s scene (within :data:`FIT_TOLERANCE_PX`).

    Examples
    --------
    >>> from geoblock.testing.synthetic import AffineCamera
    >>> scene = AffineCamera.example((1000, 1200))
    >>> crop = CroppedModel(scene, (100, 200), (300, 400))
    >>> lon, lat, h = scene.backproject(150.0, 260.0, 0.0)
    >>> [round(float(v), 6) for v in crop.project(lon, lat, h)]
    [50.0, 60.0]
    """

    name: ClassVar[str] = "crop"
    schema_version: ClassVar[int] = 1

    def __init__(self, model: SensorModel, offset: ArrayLike, shape: ArrayLike) -> None:
        row0, col0 = _offset(offset)
        size = _shape(shape)
        rows, cols = (int(v) for v in model.shape)
        if not _fits((row0, col0), size, (rows, cols)):
            raise CropError(
                f"CroppedModel: the {size[0]} x {size[1]} px crop at row/col {row0:g}, "
                f"{col0:g} does not lie inside the model's {rows} x {cols} px scene "
                f"({model.name!r})"
            )
        if isinstance(model, CroppedModel):
            row0 += model.offset[0]
            col0 += model.offset[1]
            model = model.model
        self._model = model
        self._offset = (row0, col0)
        self._shape = size

    @classmethod
    def example(cls) -> CroppedModel:
        """A 300 x 400 crop at row/col (100, 200) of a 1000 x 1200 pushbroom scene
        (``LinescanModel.example``)."""
        from geoblock.models.linescan import LinescanModel

        return cls(LinescanModel.example((1000, 1200), roll=0.01), (100.0, 200.0), (300, 400))

    # ------------------------------------------------------------------ state
    @property
    def model(self) -> SensorModel:
        """The wrapped (full-scene) model."""
        return self._model

    @property
    def offset(self) -> tuple[float, float]:
        """``(row0, col0)``: the scene pixel of the crop's first pixel."""
        return self._offset

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def source_ids(self) -> Mapping[str, str]:
        """The wrapped model's image ids (a crop keeps its scene's ids)."""
        return dict(getattr(self._model, "source_ids", None) or {})

    @property
    def height_range(self) -> tuple[float, float]:
        return self._model.height_range

    @property
    def parameters(self) -> ParameterSet:
        return self._model.parameters

    def with_parameters(self, values: ArrayLike) -> Self:
        return type(self)(self._model.with_parameters(values), self._offset, self._shape)

    def correction_curves(self, covariance: ArrayLike | None = None,
                          names: Sequence[str] | None = None, *,
                          rows: tuple[float, float] | None = None, samples: int = 200,
                          detrend: bool = True) -> tuple[CorrectionCurve, ...]:
        """The wrapped model's time-dependent corrections over the crop's rows (``rows`` in
        the crop's own rows; :class:`~geoblock.models.curves.HasCorrectionCurves`), ``()``
        when the wrapped model has none. Each curve's ``rows`` are the crop's."""
        curves = getattr(self._model, "correction_curves", None)
        if not callable(curves):
            return ()
        first, last = (0.0, self._shape[0] - 1.0) if rows is None else rows
        r0 = self._offset[0]
        found = curves(covariance, names, rows=(float(first) + r0, float(last) + r0),
                       samples=samples, detrend=detrend)
        return tuple(dataclasses.replace(c, rows=c.rows - r0) for c in found)

    @property
    def parameter_sets(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self._model.parameter_sets)

    def with_parameter_set(self, name: str, **options: Any) -> Self:
        inner = self._model.with_parameter_set(name, **options)
        return type(self)(inner, self._offset, self._shape)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "schema_version": self.schema_version,
            "offset": list(self._offset),
            "shape": list(self._shape),
            "base": self._model.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        from geoblock.errors import SerializationError
        from geoblock.plugins import from_dict

        for key in ("offset", "shape", "base"):
            if key not in data:
                raise SerializationError(f"crop model: missing field {key!r}")
        try:
            return cls(from_dict(data["base"]), data["offset"], data["shape"])
        except CropError as exc:
            raise SerializationError(f"crop model: {exc}") from exc

    # ------------------------------------------------------------------ directions
    # One path: SensorModelBase's public directions (broadcasting, NaN isolation, statuses,
    # chunking) call these kernels, which shift and hand the flat finite points to the
    # wrapped model's *_with_status (its statuses, its own chunking).
    def ground_to_image(self, lon: Float64Array, lat: Float64Array, h: Float64Array
                        ) -> KernelResult:
        (row, col), status = self._model.project_with_status(lon, lat, h)
        return row - self._offset[0], col - self._offset[1], status

    def image_to_ground(self, row: Float64Array, col: Float64Array, h: Float64Array
                        ) -> KernelResult:
        (lon, lat, _), status = self._model.backproject_with_status(
            row + self._offset[0], col + self._offset[1], h)
        return lon, lat, status

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """The wrapped model's: a shift does not change d(row, col)/d(x, y, z)."""
        return self._model.partials_ground(lon, lat, h)

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """The wrapped model's: a shift does not change d(row, col)/d(parameters)."""
        return self._model.partials_parameters(lon, lat, h)

    def __repr__(self) -> str:
        rows, cols = self._shape
        return (f"<CroppedModel {rows}x{cols} px at row/col {self._offset[0]:g}, "
                f"{self._offset[1]:g} of {self._model!r}>")


# ------------------------------------------------------------------------- reconciling
#: How a refusal names the ways out (the CLI passes its option names).
PYTHON_NAMES = {"crop_offset": "crop_offset=(ROW0, COL0)", "no_crop": "crop=False",
                "force": "force=True"}
CLI_NAMES = {"crop_offset": "--crop-offset ROW COL", "no_crop": "--no-crop", "force": "--force"}


def _check_ids(model: SensorModel, source: Any, force_name: str) -> None:
    """Refuse a model whose image ids differ from the raster's in a kind both carry."""
    model_ids = dict(getattr(model, "source_ids", None) or {})
    image_ids = dict(getattr(source, "source_ids", None) or ())
    for kind in sorted(set(model_ids) & set(image_ids)):
        if str(model_ids[kind]).strip() != str(image_ids[kind]).strip():
            origin = getattr(getattr(model, "rpc", None), "source", None) or repr(model)
            raise ModelImageMismatchError(
                f"the model describes another image than {source.path}: its {kind} is "
                f"{model_ids[kind]!r} (model {origin}) but the image's is "
                f"{image_ids[kind]!r} ({source.path}); give the model of this image, or pass "
                f"{force_name} to use this model anyway"
            )


def _fitted(model: SensorModel) -> str:
    """`` (its fitted extent: ...)`` for a model whose file states no image size."""
    if getattr(model, "shape_stated", True):
        return ""
    return (" (the extent it was fitted over: its file states no image size, and an image "
            f"within {UNSTATED_SHAPE_TOLERANCE:.0%} of it is taken as the whole scene)")


def _whole_scene_of_unstated(model: SensorModel, shape: tuple[int, ...]) -> bool:
    """Whether ``shape`` is taken as the whole scene of a model that states no image size."""
    if getattr(model, "shape_stated", True) or not callable(getattr(model, "with_shape", None)):
        return False
    return all(abs(n - fitted) <= UNSTATED_SHAPE_TOLERANCE * fitted
               for n, fitted in zip(shape, model.shape, strict=True))


def model_for_image(
    model: SensorModel,
    image: Any,
    *,
    crop_offset: ArrayLike | None = None,
    crop: bool = True,
    names: Mapping[str, str] | None = None,
    force: bool = False,
) -> SensorModel:
    """The model that addresses ``image``'s pixels: ``model``, or a :class:`CroppedModel` of it.

    First, unless ``force=True``, the model must describe this image: where both the model
    (its optional ``source_ids``, :attr:`SensorModelBase.source_ids
    <geoblock.models.base.SensorModelBase.source_ids>`) and the raster
    (:attr:`ImageSource.source_ids <geoblock.io.images.ImageSource.source_ids>`) carry an id
    of the same kind (a DigitalGlobe catalog id, a Pleiades datastrip, a DIMAP dataset name,
    a NITF ``IID2``...), the ids must be equal. Ids of different kinds, or missing on either
    side, are no evidence and pass; a crop keeps its scene's ids and passes.

    Then, in order:

    1. ``crop=False``: ``model`` as it is, whatever the shapes (image pixel ``(r, c)`` is
       model pixel ``(r, c)``; the caller says so).
    2. ``crop_offset=(row0, col0)`` given: the image is the crop of ``model``'s scene at
       that offset (it must lie inside the scene); the raster's own offset is ignored.
    3. The raster states a crop offset (``image.crop_offset``, from a pixel-unit
       geotransform): if ``model`` already has the image's shape, it is the crop's own model
       (e.g. an RPC read with ``crop_from_geotransform=True``) and is used as it is;
       otherwise the image must lie inside ``model``'s scene at that offset and the result
       is a :class:`CroppedModel`.
    4. No crop information: the shapes must be equal, or, for a model whose file states no
       image size (``model.shape_stated`` False, and the model offers ``with_shape``), the
       image's size must lie within :data:`UNSTATED_SHAPE_TOLERANCE` of the model's fitted
       extent on both axes: the result is ``model.with_shape(image.shape)``, the image being
       the whole scene (pixel ``(r, c)`` of both).

    Parameters
    ----------
    model : SensorModel
    image : ImageSource, str or os.PathLike
        The raster (opened with :func:`geoblock.io.open_image`).
    crop_offset : (float, float), optional
        ``(row0, col0)``: the scene pixel of the image's first pixel.
    crop : bool
        False: use ``model`` as it is (no shift, no shape check).
    names : mapping, optional
        How the refusal names the ways out: ``{"crop_offset": ..., "no_crop": ...,
        "force": ...}``; default the Python arguments (the CLI passes ``--crop-offset ROW
        COL``, ``--no-crop`` and ``--force``).
    force : bool
        True: skip the id check (use a model whose ids differ from the image's, e.g. a
        model known to fit although its vendor id says otherwise).

    Returns
    -------
    SensorModel

    Raises
    ------
    ModelImageMismatchError
        The model and the image carry ids of the same kind that differ (``force=False``);
        the message names both ids, both files and how to override.
    CropError
        The shapes differ and nothing says where the image lies in the scene, or the crop
        does not lie inside the scene; the message gives the image, both shapes, the offset
        and what to pass.
    """
    from geoblock.io.images import open_image

    say = dict(PYTHON_NAMES)
    say.update(names or {})
    if not crop and force:
        return model
    source = open_image(image)
    if not force:
        _check_ids(model, source, say["force"])
    if not crop:
        return model
    shape = tuple(int(v) for v in source.shape)
    scene = tuple(int(v) for v in model.shape)
    if crop_offset is not None:
        offset = _offset(crop_offset, "crop_offset")
        stated = "the crop offset given"
    elif source.crop_offset is not None:
        offset = _offset(source.crop_offset)
        if shape == scene:
            return model  # the crop's own model (its offset is folded in already)
        stated = (f"its pixel-unit geotransform (a crop starting at row/col {offset[0]:g}, "
                  f"{offset[1]:g})")
    else:
        if shape == scene:
            return model
        if _whole_scene_of_unstated(model, shape):
            return model.with_shape(shape)  # type: ignore[attr-defined]
        raise CropError(
            f"{source.path}: the image is {shape[0]} x {shape[1]} px but the model "
            f"({model.name!r}) describes a {scene[0]} x {scene[1]} px scene{_fitted(model)}, "
            "and nothing says "
            f"where the image lies in it (no pixel-unit geotransform): if the image is a crop "
            f"of the scene, pass {say['crop_offset']} (the scene pixel of its first pixel); "
            f"to use the model's pixels as they are, pass {say['no_crop']}"
        )
    try:
        return CroppedModel(model, offset, shape)  # checks that the crop lies in the scene
    except CropError as exc:  # say it in the image's terms, with the ways out
        hint = (" (the model has the image's shape: it already describes the crop, so give no "
                "offset)" if shape == scene else "")
        raise CropError(
            f"{source.path}: the {shape[0]} x {shape[1]} px image at row/col {offset[0]:g}, "
            f"{offset[1]:g} ({stated}) does not lie inside the model's "
            f"{scene[0]} x {scene[1]} px scene ({model.name!r}){hint}; pass the right "
            f"{say['crop_offset']}, or {say['no_crop']} to use the model's pixels as they are"
        ) from exc
