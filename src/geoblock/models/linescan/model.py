"""The linescan sensor model: :class:`LinescanModel`, its parameters and parameter sets.

See :mod:`geoblock.models.linescan` for the geometry and the frames.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np

from geoblock import coords
from geoblock.errors import ModelFormatError, ParameterSetError, SerializationError
from geoblock.models.base import SensorModelBase
from geoblock.models.linescan import jitter as _jitter
from geoblock.models.linescan._checks import fail
from geoblock.models.linescan.attitude import Attitude
from geoblock.models.linescan.ephemeris import Ephemeris
from geoblock.models.linescan.light import (
    apparent_direction,
    check_corrections,
    geometric_direction,
)
from geoblock.models.linescan.line_times import LineTimes
from geoblock.models.linescan.look import LookDirections
from geoblock.models.linescan.presets import (
    ALL_NAMES as _ALL_NAMES,
)
from geoblock.models.linescan.presets import (
    PARAMETER_NAMES,
    PARAMETER_UNITS,
    dg_parameters,
    physical_parameters,
)
from geoblock.models.linescan.rotations import matrix_to_quaternion, orbital_frame, rotation_xyz
from geoblock.models.parameters import ParameterSet, accuracy_or_stored, location_accuracy
from geoblock.pixels import image_domain
from geoblock.typing import ArrayLike, Float64Array, Status, StatusArray

if TYPE_CHECKING:
    from geoblock.models.curves import CorrectionCurve

__all__ = ["LinescanModel"]

_CONVERGED = np.uint8(Status.CONVERGED)
_OUT = np.uint8(Status.OUT_OF_DOMAIN)


class LinescanModel(SensorModelBase):
    """A pushbroom sensor from ephemeris, attitude, detector look directions and line times.

    Parameters
    ----------
    shape : (int, int)
        ``(rows, cols)``; ``cols`` must equal the number of look directions.
    ephemeris : Ephemeris
    attitude : Attitude
    look : LookDirections
    line_times : LineTimes
    epoch : str
        ISO-8601 UTC time all times are relative to (informational).
    height_range : (float, float)
        Valid heights, metres above the ellipsoid.
    parameters : ParameterSet, optional
        Values (and sigmas, adjustable mask) of some or all of :data:`PARAMETER_NAMES` and
        :data:`OPTIONAL_PARAMETER_NAMES` (missing ones are 0 and fixed out of the set);
        default the twelve :data:`PARAMETER_NAMES`, zero, free.
    location_accuracy_m : float, optional
        The product's stated location accuracy (1 sigma, metres, > 0), from which the ``"dg"``
        parameter set derives its a-priori sigmas when :meth:`with_parameter_set` gets no
        ``accuracy_m``; None (default) when unknown. Informational otherwise.
    corrections : sequence of str, optional
        Light-path corrections to apply, names from
        :data:`~geoblock.models.linescan.light.CORRECTIONS`: ``"aberration"``,
        ``"light-time"``, ``"refraction"`` (:mod:`geoblock.models.linescan.light`). Default
        none: the line of sight is the straight line to the ground, as for sensors whose
        calibrated look directions absorb these effects (SPOT DIMAP).
    jitter : JitterSpline, optional
        The knot grid of the attitude (and position) correction splines whose coefficients
        ``parameters`` may name (``roll_spline_000`` ...,
        :mod:`geoblock.models.linescan.jitter`); the ``"jitter"`` parameter set sets it.
        Default none.

    Notes
    -----
    With ``dt = t - line_times.reference_time_s`` the corrected state at time ``t`` is

    * ``P'(t) = P(t) + M_orb(t) @ [a, c, -r]`` with ``a = dp_along + dp_along_rate dt``,
      ``c = dp_across + dp_across_rate dt``, ``r = dp_radial + dp_radial_rate dt``;
    * ``R'(t) = R(t) @ Rx(roll) @ Ry(pitch) @ Rz(yaw)``, each angle ``bias + rate * dt``,
      ``R(t)`` sensor -> ECEF (``M_orb(t) @ R_att(t)`` for an orbital-frame attitude);
    * with a :attr:`jitter` grid, each angle (and with position splines each offset ``a, c,
      r``) adds its cubic B-spline in time ``sum_k c_k B_k(t)``
      (:mod:`geoblock.models.linescan.jitter`).

    * ``look'(col) = normalise(look_x, look_y, look_z (1 + focal_scale))``.

    Image -> ground intersects ``P' + s u`` with the surface of height ``h``, ``u`` the line
    of sight ``R' look'(col)`` corrected to the straight line to the ground
    (:func:`~geoblock.models.linescan.light.geometric_direction`) when :attr:`corrections`
    are set; ground -> image searches the time at which the ground point's apparent
    direction is in the detector plane.

    Parameter sets (:attr:`parameter_sets`, :meth:`with_parameter_set`): ``"default"``,
    ``"linescan"`` (all twelve free), ``"dg"`` (:func:`dg_parameters`), ``"physical"``
    (:func:`physical_parameters`) and ``"jitter"`` (one of these plus attitude splines in
    time, :mod:`geoblock.models.linescan.jitter`).
    """

    name: ClassVar[str] = "linescan"
    schema_version: ClassVar[int] = 1
    parameter_sets: ClassVar[tuple[str, ...]] = ("default", "linescan", "dg", "physical",
                                                 "jitter")

    #: ray/height-surface intersection: tolerance (metres of height) and iteration cap
    intersection_tolerance_m: ClassVar[float] = 1e-7
    intersection_max_iterations: ClassVar[int] = 10
    #: time search: tolerance (fraction of a line period) and iteration cap
    search_tolerance_lines: ClassVar[float] = 1e-9
    search_max_iterations: ClassVar[int] = 60
    #: a step below this many lines that does not reduce the residual ends the search
    search_stall_lines: ClassVar[float] = 1e-7
    #: points handed to the kernels at once by the base class (bounds the memory of large
    #: calls: ~125 MiB per 10^6 points instead of ~800)
    chunk_points: ClassVar[int | None] = 65536
    #: the time search covers the image rows plus a margin on each side, the larger of this
    #: fraction of the image's duration and ``search_margin_s`` seconds (limited to the
    #: ephemeris and attitude spans); ground points imaged outside it are OUT_OF_DOMAIN
    search_margin_fraction: ClassVar[float] = 0.5
    search_margin_s: ClassVar[float] = 1.0

    def __init__(
        self,
        shape: tuple[int, int],
        ephemeris: Ephemeris,
        attitude: Attitude,
        look: LookDirections,
        line_times: LineTimes,
        *,
        epoch: str = "",
        height_range: tuple[float, float] = (-500.0, 9000.0),
        parameters: ParameterSet | None = None,
        location_accuracy_m: float | None = None,
        corrections: tuple[str, ...] | list[str] | None = None,
        jitter: _jitter.JitterSpline | None = None,
    ) -> None:
        try:
            rows, cols = (int(v) for v in shape)
        except (TypeError, ValueError):
            raise fail("LinescanModel.shape", f"must be (rows, cols), got {shape!r}") from None
        if rows < 1 or cols < 2:
            raise fail("LinescanModel.shape", f"must be >= (1, 2), got {(rows, cols)}")
        for name, value, kind in (("ephemeris", ephemeris, Ephemeris),
                                  ("attitude", attitude, Attitude),
                                  ("look", look, LookDirections),
                                  ("line_times", line_times, LineTimes)):
            if not isinstance(value, kind):
                raise fail(f"LinescanModel.{name}",
                            f"must be a {kind.__name__}, got {type(value).__name__}")
        if look.cols != cols:
            raise fail("LinescanModel.look", f"look-direction table has {look.cols} detectors, "
                                              f"the image has {cols} columns")
        try:
            if isinstance(height_range, (str, bytes)):
                raise TypeError
            h0, h1 = (float(v) for v in height_range)
        except (TypeError, ValueError):
            raise fail("LinescanModel.height_range", f"must be two heights (h_min, h_max) in "
                                                      f"metres, got {height_range!r}") from None
        if not (np.isfinite(h0) and np.isfinite(h1) and h0 < h1):
            raise fail("LinescanModel.height_range", f"must be finite with h_min < h_max, got "
                                                      f"{(h0, h1)}")
        if parameters is None:
            parameters = ParameterSet(PARAMETER_NAMES, np.zeros(12), PARAMETER_UNITS)
        if not isinstance(parameters, ParameterSet):
            raise fail("LinescanModel.parameters",
                        f"must be a ParameterSet, got {type(parameters).__name__}")
        if jitter is not None and not isinstance(jitter, _jitter.JitterSpline):
            raise fail("LinescanModel.jitter",
                       f"must be a JitterSpline or None, got {type(jitter).__name__}")
        known = _jitter.known_names(jitter)
        unknown = [n for n in parameters.names if n not in known]
        if unknown:
            spline = ("" if jitter is not None else
                      "; spline coefficients need a jitter grid (with_parameter_set('jitter'))")
            raise fail("LinescanModel.parameters",
                        f"unknown parameter names {unknown[:8]}; known: {list(_ALL_NAMES)} "
                        f"and the jitter grid's coefficients{spline}")
        if not np.all(np.isfinite(parameters.values)):
            raise fail("LinescanModel.parameters", "values must be finite")
        corrections = check_corrections(corrections, "LinescanModel.corrections")
        if location_accuracy_m is not None:
            location_accuracy_m = location_accuracy(
                location_accuracy_m, "LinescanModel.location_accuracy_m (or None)")
        self._shape = (rows, cols)
        self._ephemeris = ephemeris
        self._attitude = attitude
        self._look = look
        self._line_times = line_times
        self._epoch = str(epoch)
        self._height_range = (h0, h1)
        self._parameters = parameters
        self._location_accuracy_m = location_accuracy_m
        self._corrections = corrections
        self._jitter = jitter
        where = {n: k for k, n in enumerate(known)}
        self._index = np.array([where[n] for n in parameters.names], dtype=np.intp)
        full = np.zeros(len(known))
        full[self._index] = parameters.values
        self._full = full[:12]  # the 12 values in PARAMETER_NAMES order
        # spline coefficients (6, n): roll, pitch, yaw, along, across, radial (None: no grid)
        self._coef: np.ndarray | None = None
        self._spline_att = self._spline_pos = False
        if jitter is not None:
            coef = np.zeros((6, jitter.n_coefficients))
            n_axes = len(jitter.axes)
            coef[:n_axes] = full[len(_ALL_NAMES):].reshape(n_axes, -1)
            self._coef = coef
            self._spline_att = bool(np.any(coef[:3]))
            self._spline_pos = bool(np.any(coef[3:]))
        self._focal = 1.0 + float(full[12])  # 1 + focal_scale
        if not self._focal > 0.1:
            raise fail("LinescanModel.parameters",
                       f"focal_scale must be > -0.9 (a principal distance > 0), got "
                       f"{full[12]!r}")
        self._span = self._search_span()

    # ------------------------------------------------------------------ properties
    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

    @property
    def height_range(self) -> tuple[float, float]:
        return self._height_range

    @property
    def parameters(self) -> ParameterSet:
        return self._parameters

    @property
    def ephemeris(self) -> Ephemeris:
        """The satellite's ephemeris (uncorrected)."""
        return self._ephemeris

    @property
    def attitude(self) -> Attitude:
        """The sensor's attitude (uncorrected)."""
        return self._attitude

    @property
    def look(self) -> LookDirections:
        """The detectors' look directions."""
        return self._look

    @property
    def line_times(self) -> LineTimes:
        """Row exposure times."""
        return self._line_times

    @property
    def epoch(self) -> str:
        """ISO-8601 UTC epoch of all times (informational)."""
        return self._epoch

    @property
    def location_accuracy_m(self) -> float | None:
        """The product's stated location accuracy (1 sigma, metres), or None if unknown."""
        return self._location_accuracy_m

    @property
    def jitter(self) -> _jitter.JitterSpline | None:
        """The knot grid of the correction splines (:mod:`geoblock.models.linescan.jitter`),
        or None."""
        return self._jitter

    def correction_curves(self, covariance: ArrayLike | None = None,
                          names: Sequence[str] | None = None, *,
                          rows: tuple[float, float] | None = None, samples: int = 200,
                          detrend: bool = True) -> tuple[CorrectionCurve, ...]:
        """The ``"jitter"`` set's attitude (and position) correction curves over the image
        with their sigma bands, ``()`` without a :attr:`jitter` grid
        (:class:`~geoblock.models.curves.HasCorrectionCurves`;
        :func:`~geoblock.models.linescan.jitter.correction_curves`)."""
        return _jitter.correction_curves(self, covariance, names, rows=rows, samples=samples,
                                         detrend=detrend)

    @property
    def corrections(self) -> tuple[str, ...]:
        """The light-path corrections applied (:mod:`geoblock.models.linescan.light`)."""
        return self._corrections

    def with_parameters(self, values: ArrayLike | Mapping[str, float]) -> Self:
        return self.replace(parameters=self._parameters.with_values(values))

    def replace(self, **changes: Any) -> Self:
        """A copy with some constructor arguments replaced (``ephemeris=...``, ``shape=...``,
        ``location_accuracy_m=...``, ``corrections=...``, ``jitter=...``)."""
        args: dict[str, Any] = {
            "shape": self._shape, "ephemeris": self._ephemeris, "attitude": self._attitude,
            "look": self._look, "line_times": self._line_times, "epoch": self._epoch,
            "height_range": self._height_range, "parameters": self._parameters,
            "location_accuracy_m": self._location_accuracy_m,
            "corrections": self._corrections, "jitter": self._jitter}
        unknown = set(changes) - set(args)
        if unknown:
            raise TypeError(f"replace: unknown fields {sorted(unknown)}")
        args.update(changes)
        return type(self)(
            args["shape"], args["ephemeris"], args["attitude"], args["look"], args["line_times"],
            epoch=args["epoch"], height_range=args["height_range"],
            parameters=args["parameters"], location_accuracy_m=args["location_accuracy_m"],
            corrections=args["corrections"], jitter=args["jitter"])

    # ------------------------------------------------------------------ parameter sets
    def with_parameter_set(self, name: str, **options: Any) -> Self:
        """A copy whose parameters are the preset ``name`` (see :attr:`parameter_sets`).

        Parameters
        ----------
        name : {"default", "linescan", "dg", "physical", "jitter"}
            * ``"default"``: the parameters as they are (returns ``self``);
            * ``"linescan"``: all twelve :data:`PARAMETER_NAMES`, free (infinite sigmas),
              adjustable;
            * ``"dg"``: Teo et al.'s direct-georeferencing set, :func:`dg_parameters`:
              position biases and drifts and attitude biases adjustable
              (:data:`DG_ADJUSTABLE`) with a-priori sigmas from the location accuracy,
              attitude rates fixed;
            * ``"physical"``: a physical set in the spirit of Toutin's CCRS model,
              :func:`physical_parameters`: attitude biases and drifts, along- and
              across-track position biases and the focal scale (:data:`PHYSICAL_ADJUSTABLE`),
              a-priori sigmas from the location accuracy;
            * ``"jitter"``: the set ``base`` plus roll, pitch and yaw corrections as cubic
              B-splines in time (:mod:`geoblock.models.linescan.jitter`,
              :func:`~geoblock.models.linescan.jitter.jitter_parameters`): coefficients
              ``roll_spline_000`` ... (rad), adjustable, with an amplitude and a
              second-difference smoothness prior carried as the set's ``information``.

            A ``focal_scale`` other than 0, and spline coefficients other than 0, stay in every
            set (fixed where the set does not adjust them).
        **options
            ``accuracy_m`` (float, ``"dg"``, ``"physical"`` and ``"jitter"`` on those bases):
            the location accuracy (1 sigma, metres) the sigmas derive from; default
            :attr:`location_accuracy_m`. ``"jitter"`` also takes ``base`` (``"dg"``
            (default), ``"physical"`` or ``"linescan"``), ``knot_lines`` (knot spacing, lines,
            >= 1; default the current grid's, else
            :func:`~geoblock.models.linescan.jitter.default_knot_lines`, the attitude record's
            sampling), ``sigma_rad`` (amplitude sigma, default
            :data:`~geoblock.models.linescan.jitter.DEFAULT_JITTER_SIGMA_RAD`),
            ``smoothness_rad`` (sigma of a second difference per knot interval; default
            :func:`~geoblock.models.linescan.jitter.default_smoothness`), ``position``
            (bool, default as the current grid, else False: also along/across/radial
            position splines, coefficients
            ``dp_along_spline_000`` ... in metres) with ``position_sigma_m`` and
            ``position_smoothness_m`` (default the attitude sigmas times the slant range).

        Returns
        -------
        LinescanModel
            The same geometry: a preset sets names, units, a-priori sigmas and the adjustable
            mask, and **keeps the current values** of the twelve parameters (0 for those the
            current set leaves out, which is what the model uses for them), so it never
            changes a projection nor drops a correction. The a-priori sigmas are about these
            current values (an adjustment's pseudo-observations are centred on them); a full
            a-priori ``covariance`` of the current set is replaced by the preset's sigmas.

        Raises
        ------
        ParameterSetError
            An unknown name or option, or ``"dg"`` with neither ``accuracy_m`` nor
            :attr:`location_accuracy_m`, or a ``"jitter"`` grid other than the current one
            while spline coefficients are not 0.
        """
        if name == "jitter":
            self._parameter_set_request(name, options, _jitter.JITTER_OPTIONS)
            spline, params = _jitter.jitter_set(self, **options)
            return self.replace(jitter=spline, parameters=self._keep_values(params, spline))
        if name == "linescan":
            self._parameter_set_request(name, options)
            params = ParameterSet(PARAMETER_NAMES, self._full, PARAMETER_UNITS)
        elif name in ("dg", "physical"):
            self._parameter_set_request(name, options, ("accuracy_m",))
            accuracy = accuracy_or_stored(options.get("accuracy_m"), self._location_accuracy_m,
                                          f"{type(self).__qualname__} {self.name!r}", name)
            preset = dg_parameters if name == "dg" else physical_parameters
            params = preset(self, accuracy)
        else:
            return super().with_parameter_set(name, **options)
        return self.replace(parameters=self._keep_values(params))

    def _keep_values(self, params: ParameterSet,
                     spline: _jitter.JitterSpline | None = None) -> ParameterSet:
        """``params`` with the current values; a non-zero focal scale and non-zero spline
        coefficients that ``params`` leaves out kept (fixed). ``spline``: the new model's
        grid (default the current one)."""
        spline = self._jitter if spline is None else spline
        now = dict(zip(_ALL_NAMES, np.append(self._full, self._focal - 1.0), strict=True))
        units = dict(zip(_ALL_NAMES, PARAMETER_UNITS + ("1",), strict=True))
        if self._jitter is not None and self._coef is not None:
            n_axes = len(self._jitter.axes)
            now.update(zip(self._jitter.names, self._coef[:n_axes].ravel(), strict=True))
            units.update(zip(self._jitter.names, self._jitter.units, strict=True))
        extra = [n for n, v in now.items() if v != 0 and n not in params.names]
        if spline != self._jitter and self._coef is not None and np.any(self._coef):
            raise ParameterSetError(
                f"{type(self).__qualname__} {self.name!r}: the spline coefficients are not 0 "
                f"on the current jitter grid ({self._jitter}); a new grid ({spline}) would "
                "drop that correction: ask for the current grid's knot_lines")
        if extra:
            k = len(extra)
            info = None
            if params.information is not None:  # the kept ones free (zero rows) and fixed
                info = np.zeros((len(params) + k, len(params) + k))
                info[:len(params), :len(params)] = params.information
            params = ParameterSet(
                params.names + tuple(extra), np.append(params.values, np.zeros(k)),
                params.units + tuple(units[n] for n in extra),
                None if info is not None else np.append(params.sigmas, np.full(k, np.inf)),
                np.append(params.adjustable, np.zeros(k, bool)), _pad_free(params.covariance, k),
                information=info)
        return params.with_values([float(now.get(n, 0.0)) for n in params.names])

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        out = {
            "model": self.name,
            "schema_version": self.schema_version,
            "shape": list(self._shape),
            "epoch": self._epoch,
            "height_range": list(self._height_range),
            "ephemeris": self._ephemeris.to_dict(),
            "attitude": self._attitude.to_dict(),
            "look": self._look.to_dict(),
            "line_times": self._line_times.to_dict(),
            "parameters": self._parameters.to_dict(),
        }
        if self._location_accuracy_m is not None:  # absent from older JSON: stays optional
            out["location_accuracy_m"] = self._location_accuracy_m
        if self._corrections:  # likewise
            out["corrections"] = list(self._corrections)
        if self._jitter is not None:  # likewise
            out["jitter"] = self._jitter.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Self:
        try:
            if data.get("model", cls.name) != cls.name:
                raise SerializationError(f"not a {cls.name} model: model={data.get('model')!r}")
            version = data.get("schema_version", cls.schema_version)
            if version != cls.schema_version:
                raise SerializationError(f"{cls.name}: unsupported schema_version {version!r} "
                                         f"(this geoblock reads {cls.schema_version})")
            return cls(
                tuple(data["shape"]),
                Ephemeris.from_dict(data["ephemeris"]),
                Attitude.from_dict(data["attitude"]),
                LookDirections.from_dict(data["look"]),
                LineTimes.from_dict(data["line_times"]),
                epoch=data.get("epoch", ""),
                height_range=tuple(data.get("height_range", (-500.0, 9000.0))),
                parameters=ParameterSet.from_dict(data["parameters"])
                if "parameters" in data else None,
                location_accuracy_m=data.get("location_accuracy_m"),
                corrections=data.get("corrections"),
                jitter=_jitter.JitterSpline.from_dict(data["jitter"])
                if data.get("jitter") is not None else None,
            )
        except KeyError as exc:
            raise SerializationError(f"{cls.name}: missing field {exc}") from exc
        except ModelFormatError as exc:
            raise SerializationError(f"{cls.name}: {exc}") from exc
        except (TypeError, ValueError, AttributeError) as exc:
            if isinstance(exc, SerializationError):
                raise
            raise SerializationError(f"{cls.name}: invalid model dictionary: {exc}") from exc

    # ------------------------------------------------------------------ state
    def _params_at(self, t: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(N, 3) position offsets [a, c, -r] in the orbital frame and (N, 3) angles at flat
        times t, or None where all zero (so that zero corrections cost nothing)."""
        p = self._full
        dt = t - self._line_times.reference_time_s
        offsets = angles = None
        if np.any(p[0:6]):
            offsets = p[0:3] + dt[:, None] * p[3:6]
        if np.any(p[6:12]):
            angles = p[6:9] + dt[:, None] * p[9:12]
        if self._jitter is not None and self._coef is not None and (
                self._spline_att or self._spline_pos):
            rows = slice(0, 6) if self._spline_pos else slice(0, 3)
            spline = self._jitter.evaluate(self._coef[rows], t)
            if self._spline_att:
                angles = spline[:, :3] if angles is None else angles + spline[:, :3]
            if self._spline_pos:
                offsets = spline[:, 3:] if offsets is None else offsets + spline[:, 3:]
        if offsets is not None:
            offsets[:, 2] *= -1.0
        return offsets, angles

    def _state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Corrected state at flat times t: P' (N,3), V (N,3), R' (N,3,3), M_orb (N,3,3)."""
        pos, vel = self._ephemeris.at(t)
        m_orb = orbital_frame(pos, vel)
        rot = self._attitude.matrix(t)
        if self._attitude.frame == "orbital":
            rot = m_orb @ rot
        offsets, angles = self._params_at(t)
        if offsets is not None:
            pos = pos + np.einsum("nij,nj->ni", m_orb, offsets)
        if angles is not None:
            rot = rot @ rotation_xyz(angles[:, 0], angles[:, 1], angles[:, 2])
        return pos, vel, rot, m_orb

    def sensor_state(self, row: ArrayLike) -> tuple[Float64Array, Float64Array, Float64Array]:
        """The corrected (parameters applied) sensor state when ``row`` is exposed.

        Parameters
        ----------
        row : array_like, (...)
            Rows, pixels.

        Returns
        -------
        position_m : ndarray, (..., 3)
            Corrected ECEF position ``P'``, metres.
        velocity_m_s : ndarray, (..., 3)
            ECEF velocity from the ephemeris plus the position drift rates (and the position
            splines' time derivative) rotated to ECEF, metres per second.
        rotation : ndarray, (..., 3, 3)
            Corrected sensor -> ECEF rotation ``R'``.
        """
        r = np.asarray(row, dtype=np.float64)
        t = self._line_times.time(r).ravel()
        pos, vel, rot, m_orb = self._state(t)
        rates = self._full[3:6] * np.array([1.0, 1.0, -1.0])
        if np.any(rates):
            vel = vel + m_orb @ rates
        if self._spline_pos and self._jitter is not None and self._coef is not None:
            drift = self._jitter.evaluate(self._coef[3:], t, derivative=True)
            drift[:, 2] *= -1.0
            vel = vel + np.einsum("nij,nj->ni", m_orb, drift)
        return pos.reshape(r.shape + (3,)), vel.reshape(r.shape + (3,)), rot.reshape(
            r.shape + (3, 3))

    def _search_span(self) -> tuple[float, float]:
        """Time bracket of the ground -> image search, seconds."""
        rows = self._shape[0]
        margin = max(self.search_margin_fraction * rows,
                     self.search_margin_s / self._line_times.period_magnitude_s)
        first, _, last, _ = image_domain(self._shape)  # the image's outer edges, rows
        # either scan direction: the span is sorted (a reverse scan's row 0 is its latest)
        t0, t1 = self._line_times.span(first - margin, last + margin)
        e0, e1 = self._ephemeris.valid_span_s
        a0, a1 = self._attitude.valid_span_s
        return max(t0, e0, a0), min(t1, e1, a1)

    # ------------------------------------------------------------------ domain
    #: heights farther than the larger of this and the span of :attr:`height_range` outside
    #: that range are OUT_OF_DOMAIN (both directions): the model converges there (at -10^6 m
    #: too), but no image of the Earth's surface is meant
    height_margin_m: ClassVar[float] = 10_000.0

    def _height_outside(self, h: np.ndarray) -> np.ndarray:
        h0, h1 = self._height_range
        margin = max(h1 - h0, self.height_margin_m)
        return ~((h >= h0 - margin) & (h <= h1 + margin))

    # ------------------------------------------------------------------ image -> ground
    def image_to_ground(self, row: np.ndarray, col: np.ndarray, h: np.ndarray
                        ) -> tuple[Float64Array, Float64Array, StatusArray]:
        t = self._line_times.time(row)
        pos, vel, rot, _ = self._state(t)
        look = self._look.at(col)
        if self._focal != 1.0:
            look = look * np.array([1.0, 1.0, self._focal])
            look /= np.linalg.norm(look, axis=-1, keepdims=True)
        u = np.einsum("nij,nj->ni", rot, look)
        if self._corrections:
            u = geometric_direction(u, pos, vel, h, self._corrections)
        lon, lat, _, status = coords.intersect_height(pos, u, h, self.intersection_tolerance_m,
                                                      self.intersection_max_iterations)
        status[~np.all(np.isfinite(pos), axis=1) | ~np.all(np.isfinite(u), axis=1)] = _OUT
        status[self._height_outside(h)] = _OUT
        return lon, lat, status

    # ------------------------------------------------------------------ ground -> image
    def _apparent(self, g: np.ndarray, h: np.ndarray, pos: np.ndarray, vel: np.ndarray
                  ) -> np.ndarray:
        """``G - P`` (N, 3), turned to the apparent line of sight when corrections are set."""
        diff = g - pos
        if not self._corrections:
            return diff
        rng = np.linalg.norm(diff, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            u = diff / rng[:, None]
        pos, vel = np.broadcast_to(pos, g.shape), np.broadcast_to(vel, g.shape)
        return apparent_direction(u, pos, vel, h, self._corrections) * rng[:, None]

    def _residual(self, g: np.ndarray, h: np.ndarray, pos: np.ndarray, vel: np.ndarray,
                  rot: np.ndarray) -> tuple[Float64Array, Float64Array, Float64Array]:
        """Detector-plane residual at ground points g (heights h) for states (pos, vel, rot).

        Returns ``f = d_x/d_z - tan_x(col)``, ``col``, ``d`` (N, 3) in the sensor frame.
        """
        diff = self._apparent(g, h, pos, vel)
        if rot.ndim == 2:
            d = diff @ rot
        else:
            d = np.einsum("nji,nj->ni", rot, diff)
        with np.errstate(invalid="ignore", divide="ignore"):
            ry = d[:, 1] / d[:, 2]
            col, tx, _ = self._look.invert(ry * self._focal)
            f = d[:, 0] / d[:, 2] - tx / self._focal
        return f, col, d

    def _solve_time(self, g: np.ndarray, h: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exposure time and column of ground points g (N, 3) ECEF, heights h (N,); with a
        status."""
        n = g.shape[0]
        t_out = np.full(n, np.nan)
        col_out = np.full(n, np.nan)
        status = np.full(n, _OUT, dtype=np.uint8)
        lo, hi = self._span
        if not lo < hi:
            return t_out, col_out, status
        ends = np.array([lo, hi])
        p_end, v_end, r_end, _ = self._state(ends)
        fa, _, da = self._residual(g, h, p_end[0], v_end[0], r_end[0])
        fb, _, db = self._residual(g, h, p_end[1], v_end[1], r_end[1])
        ok = (np.isfinite(fa) & np.isfinite(fb) & (da[:, 2] > 0) & (db[:, 2] > 0)
              & (np.sign(fa) != np.sign(fb)))
        idx = np.flatnonzero(ok)
        a, fa = np.full(idx.size, lo), fa[idx]
        b, fb = np.full(idx.size, hi), fb[idx]
        # the two latest iterates (x0 older); col1, dz1: column and d_z at x1
        x0, f0, x1, f1 = a.copy(), fa.copy(), b.copy(), fb.copy()
        col1 = np.full(idx.size, np.nan)
        dz1 = np.full(idx.size, np.nan)
        gi, hi_ = g[idx], h[idx]
        tol = self.search_tolerance_lines * self._line_times.period_magnitude_s
        stall = self.search_stall_lines * self._line_times.period_magnitude_s
        status[idx] = Status.MAX_ITERATIONS

        def finish(fin: np.ndarray, good: np.ndarray) -> None:
            nonlocal idx, gi, hi_, a, fa, b, fb, x0, f0, x1, f1, col1, dz1
            sel = idx[fin]
            t_out[sel] = x1[fin]
            col_out[sel] = col1[fin]
            status[sel] = np.where(good[fin] & (dz1[fin] > 0), _CONVERGED,
                                   np.uint8(Status.DIVERGED))
            keep = ~fin
            idx, gi, hi_ = idx[keep], gi[keep], hi_[keep]
            a, fa, b, fb = a[keep], fa[keep], b[keep], fb[keep]
            x0, f0, x1, f1 = x0[keep], f0[keep], x1[keep], f1[keep]
            col1, dz1 = col1[keep], dz1[keep]

        for iteration in range(self.search_max_iterations + 1):
            if idx.size == 0:
                break
            with np.errstate(invalid="ignore", divide="ignore"):
                x = x1 - f1 * (x1 - x0) / (f1 - f0)
            if iteration > 0:
                # converged: the next secant correction is below the tolerance, or the
                # residual is zero; or float64's floor: the last step was below
                # search_stall_lines and did not reduce the residual
                done = (np.abs(x - x1) <= tol) | (f1 == 0) | (
                    (np.abs(x1 - x0) <= stall) & ~(np.abs(f1) < np.abs(f0)))
                bad = ~np.isfinite(f1)
                if iteration == self.search_max_iterations:
                    break
                if np.any(done | bad):
                    finish(done | bad, done & ~bad)
                    if idx.size == 0:
                        break
                    x = x[~(done | bad)]
            inside = (x > np.minimum(a, b)) & (x < np.maximum(a, b))
            x = np.where(inside, x, 0.5 * (a + b))
            pos, vel, rot, _ = self._state(x)
            f, col, d = self._residual(gi, hi_, pos, vel, rot)
            same = np.sign(f) == np.sign(fa)  # keep the bracket
            a = np.where(same, x, a)
            fa = np.where(same, f, fa)
            b = np.where(same, b, x)
            fb = np.where(same, fb, f)
            x0, f0, x1, f1, col1, dz1 = x1, f1, x, f, col, d[:, 2]
        return t_out, col_out, status

    def ground_to_image(self, lon: np.ndarray, lat: np.ndarray, h: np.ndarray
                        ) -> tuple[Float64Array, Float64Array, StatusArray]:
        # no place on the Earth (lon=1e300 is some longitude once in sin/cos) or a height far
        # outside the model's range: OUT_OF_DOMAIN, not solved
        outside = (~((np.abs(lon) <= 540.0) & (np.abs(lat) <= 90.0))
                   | self._height_outside(h))
        if np.any(outside):
            row = np.full(lon.shape, np.nan)
            col = np.full(lon.shape, np.nan)
            status = np.full(lon.shape, _OUT, dtype=np.uint8)
            keep = ~outside
            if np.any(keep):
                row[keep], col[keep], status[keep] = self.ground_to_image(
                    lon[keep], lat[keep], h[keep])
            return row, col, status
        g = np.stack(coords.geodetic_to_ecef(lon, lat, h), axis=-1)
        t, col, status = self._solve_time(g, h)
        return self._line_times.row(t), col, status

    def ground_seed(self) -> tuple[float, float]:
        rows, cols = self._shape
        g, status = self.backproject_with_status((rows - 1) / 2.0, (cols - 1) / 2.0, 0.0)
        return float(g.lon), float(g.lat)

    # ------------------------------------------------------------------ partials
    #: time step (seconds) of the central difference giving d(residual)/dt in the partials
    partials_time_step_s: ClassVar[float] = 1e-4

    def _implicit(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> tuple[
            tuple[int, ...], np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
            np.ndarray]:
        """Solve the point, then the (N, 2, 2) Jacobian of (E1, E2) in (t, col) and pieces.

        ``rot`` is returned as ``R'`` times the (N, 3, 3) Jacobian of the light-path
        corrections' map ``G - P -> apparent line of sight`` (identity without corrections),
        so that ``d(d)/d(G - P) = rot^T``.
        """
        lon, lat, h = (np.asarray(v, np.float64) for v in np.broadcast_arrays(lon, lat, h))
        shape = lon.shape
        g = np.stack(coords.geodetic_to_ecef(lon.ravel(), lat.ravel(), h.ravel()), axis=-1)
        t, col, status = self._solve_time(g, h.ravel())
        ok = status == _CONVERGED
        t = np.where(ok, t, np.nan)
        pos, vel, rot, m_orb = self._state(t)
        hr = h.ravel()
        diff = self._apparent(g, hr, pos, vel)
        d = np.einsum("nji,nj->ni", rot, diff)
        if self._corrections:
            # Jacobian of the corrections (I + O(1e-5)) by central differences of 1 m
            jac_a = np.empty((t.size, 3, 3))
            for k in range(3):
                unit = np.zeros(3)
                unit[k] = 1.0
                jac_a[:, :, k] = 0.5 * (self._apparent(g + unit, hr, pos, vel)
                                        - self._apparent(g - unit, hr, pos, vel))
            rot = np.swapaxes(jac_a, -1, -2) @ rot  # (R^T J)^T
        dz = d[:, 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            # d(E1, E2)/d(d): E1 = d_x/d_z - Tx, E2 = d_y/d_z - Ty
            de_dd = np.zeros((t.size, 2, 3))
            de_dd[:, 0, 0] = 1.0 / dz
            de_dd[:, 0, 2] = -d[:, 0] / (dz * dz)
            de_dd[:, 1, 1] = 1.0 / dz
            de_dd[:, 1, 2] = -d[:, 1] / (dz * dz)
            _, _, dtan = self._look.invert(d[:, 1] / dz * self._focal)
            dtan = dtan / self._focal
            # d(E)/dt at fixed G and col: central difference of the sensor-frame ratios
            step = self.partials_time_step_s
            ratios = []
            for sign in (1.0, -1.0):
                p_s, v_s, r_s, _ = self._state(t + sign * step)
                ds = np.einsum("nji,nj->ni", r_s, self._apparent(g, hr, p_s, v_s))
                ratios.append(ds[:, :2] / ds[:, 2:3])
            de_dt = (ratios[0] - ratios[1]) / (2.0 * step)
        jac = np.stack([de_dt, -dtan], axis=-1)  # (N, 2, 2): columns d/dt, d/dcol
        return shape, t, d, rot, m_orb, de_dd, jac

    def partials_ground(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """d(row, col)/d(x, y, z) ECEF, pixels per metre, (*S, 2, 3).

        Implicit-function theorem on the two detector-plane equations
        ``d_x/d_z = tan_x(col)``, ``d_y/d_z = tan_y(col)`` with ``d = R'(t)^T (G - P'(t))``;
        their time derivative is a central difference of ``partials_time_step_s``.
        """
        return self._ground_partials(self._implicit(lon, lat, h))

    def partials(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike
                 ) -> tuple[Float64Array, Float64Array]:
        """``(partials_ground, partials_parameters)`` from one solution of the points (the
        line search and the orbit state shared: half the work of the two calls)."""
        imp = self._implicit(lon, lat, h)
        return self._ground_partials(imp), self._parameter_partials(imp)

    def _ground_partials(self, imp: tuple[Any, ...]) -> Float64Array:
        shape, t, d, rot, m_orb, de_dd, jac = imp
        de_dg = de_dd @ np.swapaxes(rot, -1, -2)  # (N, 2, 3)
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = -np.linalg.solve(_nan_safe(jac), de_dg)  # (N, 2, 3): d(t, col)/dG
        sol[~np.isfinite(t)] = np.nan
        sol[:, 0, :] /= self._line_times.line_period_s
        return sol.reshape(shape + (2, 3))

    def partials_parameters(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> Float64Array:
        """d(row, col)/d(parameter k), pixels per parameter unit, (*S, 2, P).

        Analytic in the parameters (``dd/dp`` of the sensor-frame vector) through the
        implicit-function theorem, as :meth:`partials_ground`. A spline coefficient's partial
        is its basis function at the exposure time times its axis's bias partial: nonzero for
        four coefficients per axis and point.
        """
        return self._parameter_partials(self._implicit(lon, lat, h))

    def _parameter_partials(self, imp: tuple[Any, ...]) -> Float64Array:
        shape, t, d, rot, m_orb, de_dd, jac = imp
        n = t.size
        dt = t - self._line_times.reference_time_s
        dd_dp = np.zeros((n, 3, len(_ALL_NAMES)))
        # position: d = R'^T (G - P'), dP'/dp = M_orb[:, :, k] (x dt for the rates)
        rt_m = np.einsum("nji,njk->nik", rot, m_orb)  # R'^T M_orb
        rt_m[:, :, 2] *= -1.0  # radial is up = -z_o
        dd_dp[:, :, 0:3] = -rt_m
        dd_dp[:, :, 3:6] = -rt_m * dt[:, None, None]
        # attitude: dd/d(angle_k) = -a_k x d, a_roll = (Ry Rz)^T ex, a_pitch = Rz^T ey, a_yaw = ez
        ang = self._params_at(t)[1]
        if ang is None:
            ang = np.zeros((n, 3))
        cb, sb = np.cos(ang[:, 1]), np.sin(ang[:, 1])
        cc, sc = np.cos(ang[:, 2]), np.sin(ang[:, 2])
        axis_roll = np.stack([cb * cc, -cb * sc, sb], axis=-1)  # first row of Ry Rz
        axis_pitch = np.stack([sc, cc, np.zeros_like(cc)], axis=-1)  # second row of Rz
        axis_yaw = np.broadcast_to([0.0, 0.0, 1.0], (n, 3))
        for k, axis in enumerate((axis_roll, axis_pitch, axis_yaw)):
            col = -np.cross(axis, d)
            dd_dp[:, :, 6 + k] = col
            dd_dp[:, :, 9 + k] = col * dt[:, None]
        de_dp = de_dd @ dd_dp  # (N, 2, 13)
        # focal scale: E = d_xy/d_z - tan0(col) / (1 + s), so dE/ds = tan'(col) / (1 + s),
        # and tan'(col) = d_xy/d_z at the solution
        with np.errstate(invalid="ignore", divide="ignore"):
            de_dp[:, :, 12] = d[:, :2] / d[:, 2:3] / self._focal
        with np.errstate(invalid="ignore", divide="ignore"):
            sol = -np.linalg.solve(_nan_safe(jac), de_dp)
        sol[~np.isfinite(t)] = np.nan
        sol[:, 0, :] /= self._line_times.line_period_s
        n_base = len(_ALL_NAMES)
        base = self._index < n_base
        if base.all():
            return sol[:, :, self._index].reshape(shape + (2, len(self._index)))
        out = np.zeros((n, 2, len(self._index)))
        out[:, :, base] = sol[:, :, self._index[base]]
        assert self._jitter is not None
        columns = _jitter.spline_columns(self._jitter, self._parameters.names)
        # d/d(coefficient) = B_k(t) d/d(bias): roll/pitch/yaw biases, then dp_along/across/radial
        axis_bias = sol[:, :, [6, 7, 8, 0, 1, 2]]
        _jitter.scatter_partials(self._jitter, columns, np.where(np.isfinite(t), t, 0.0),
                                 axis_bias, out)
        out[~np.isfinite(t)] = np.nan
        return out.reshape(shape + (2, len(self._index)))

    # ------------------------------------------------------------------ example
    @classmethod
    def example(cls, shape: tuple[int, int] = (800, 1000), *, roll: float = 0.05,
                frame: str = "orbital") -> LinescanModel:
        """A 2.5 m GSD scanner on a 700 km circular orbit over Nice, France.

        The orbit ignores the Earth's rotation (a circle in ECEF through the zenith of
        (7.05 E, 43.7 N), heading 190 degrees); the attitude, sampled every 0.05 s in the
        orbital frame, rolls by ``roll`` radians with a small pitch, yaw and a slow wobble;
        the detectors have a slight along-track curvature. ``frame="ecef"`` stores the same
        attitude as sensor -> ECEF quaternions.
        """
        rows, cols = (int(v) for v in shape)
        alt, gsd = 700e3, 2.5
        lon0, lat0 = np.radians(7.05), np.radians(43.70)
        centre = np.array([np.cos(lat0) * np.cos(lon0), np.cos(lat0) * np.sin(lon0), np.sin(lat0)])
        enu = coords.enu_rotation(7.05, 43.70)
        heading = np.radians(190.0)
        along = np.sin(heading) * enu[0] + np.cos(heading) * enu[1]
        radius = coords.WGS84_A + alt
        omega = np.sqrt(3.986004418e14 / radius**3)
        speed = omega * coords.WGS84_A * 0.99
        line_period = gsd / speed
        half = 0.6 * rows * line_period + 2.0
        t_eph = np.arange(-np.ceil(half), np.ceil(half) + 1.0, 1.0)
        ang = omega * t_eph
        pos = radius * (np.cos(ang)[:, None] * centre + np.sin(ang)[:, None] * along)
        vel = radius * omega * (-np.sin(ang)[:, None] * centre + np.cos(ang)[:, None] * along)
        ephemeris = Ephemeris(t_eph, pos, vel)
        t_att = np.arange(-half, half + 0.05, 0.05)
        wobble = 2e-5 * np.sin(2 * np.pi * 0.3 * t_att)
        r_att = rotation_xyz(roll + wobble, 0.01 + 0.5 * wobble, 0.002 + 0 * t_att)
        if frame == "ecef":
            p_att, v_att = ephemeris.at(t_att)
            r_att = orbital_frame(p_att, v_att) @ r_att
        attitude = Attitude(t_att, matrix_to_quaternion(r_att), frame=frame)
        c = np.arange(cols) - (cols - 1) / 2.0
        ifov = gsd / alt
        look = LookDirections.from_tan_angles(2e-4 + 1e-10 * c**2, c * ifov)
        lines = LineTimes((rows - 1) / 2.0, 0.0, line_period)
        return cls((rows, cols), ephemeris, attitude, look, lines,
                   epoch="2003-06-21T02:30:00Z")


# ==================================================================================== internals
def _pad_free(cov: np.ndarray | None, k: int) -> np.ndarray | None:
    """A covariance with ``k`` free parameters appended (``inf`` variance), or None."""
    if cov is None:
        return None
    out = np.pad(np.asarray(cov, dtype=np.float64), (0, k))
    idx = np.arange(cov.shape[0], cov.shape[0] + k)
    out[idx, idx] = np.inf
    return out


def _nan_safe(jac: np.ndarray) -> np.ndarray:
    """Replace non-finite or singular 2x2 systems by the identity (their results are masked)."""
    bad = ~np.all(np.isfinite(jac), axis=(-2, -1))
    det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
    bad |= ~(det != 0)
    if bad.any():
        jac = jac.copy()
        jac[bad] = np.eye(2)
    return jac
