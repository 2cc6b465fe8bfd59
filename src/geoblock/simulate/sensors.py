"""Simulated satellites: a true and an on-board :class:`~geoblock.models.linescan.LinescanModel`.

:func:`simulate_sensor` turns an :class:`OrbitSensorSpec` (orbit, viewing angles, GSD, image
shape, line period, attitude jitter, on-board error budget, seed) into a
:class:`SimulatedSensor`:

* the **true** model: a circular Keplerian orbit propagated in an inertial frame and rotated
  to ECEF with the Earth's rotation (ECEF positions and Earth-fixed velocities), sampled every
  ``ephemeris_step_s`` over the scene plus a margin; attitude quaternions in the orbital frame
  sampled at ``attitude_rate_hz`` with the requested roll and pitch plus a sinusoidal jitter;
  a linear array of detectors whose focal-plane tangents give the requested GSD at nadir;
  row times centred on the scene centre, which the image centre sees at the centre height;
* the **on-board** model: the same with the ephemeris and attitude a real satellite would
  report: position bias and drift in the orbital frame and attitude bias and drift (no
  jitter: it is not observed), drawn from the seeded RNG and scaled so that the on-board
  geolocation error has the requested RMSE (Teo et al. Table II: 6-38 m per axis for
  SPOT-5), with a requested share of along-track drift growing with the distance from the
  image centre (Aguilar et al., QuickBird basic imagery).

With ``onboard_errors="realistic"`` (the default) the two also differ as real on-board data
do (:mod:`geoblock.simulate.onboard`, sizes measured on the real products in
``../shared/data``): the true attitude has a band-limited wander the on-board attitude does
not know, the true look directions a smooth interior-orientation error, and the on-board
ephemeris an error at the orbital period; the biases and drifts are scaled so that the total
on-board RMSE is still ``onboard_rmse_m``. ``onboard_errors="bias-drift"`` gives the
simulator's earlier models, bit for bit.

:func:`onboard_error` measures the on-board model's ground error against the true model.

Presets (plain :class:`OrbitSensorSpec` instances): :data:`SPOT5_STRIPS` (Teo et al.'s three
strips), :data:`QUICKBIRD` (Aguilar et al.), :data:`SPOT1A` (Chen & Lee), and small variants
(``*_SMALL``: image shape divided and GSD multiplied by the same factor, same footprint) that
build in a fraction of a second. Everything is deterministic for a given ``seed``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from geoblock import coords
from geoblock.errors import GeoblockError
from geoblock.models.linescan import (
    Attitude,
    Ephemeris,
    LinescanModel,
    LineTimes,
    LookDirections,
    matrix_to_quaternion,
    orbital_frame,
    rotation_xyz,
)
from geoblock.pixels import image_domain
from geoblock.simulate import onboard as _onboard
from geoblock.simulate.onboard import ONBOARD_ERRORS, RealisticErrors, WanderSpectrum
from geoblock.typing import Float64Array

__all__ = [
    "EARTH_ROTATION_RAD_S",
    "GM_M3_S2",
    "QUICKBIRD",
    "QUICKBIRD_SMALL",
    "SPOT1A",
    "SPOT1A_SMALL",
    "SPOT5_STRIPS",
    "SPOT5_STRIPS_SMALL",
    "SPOT_HRG20",
    "GroundError",
    "OnboardErrors",
    "OrbitSensorSpec",
    "SimulatedSensor",
    "incidence_angle",
    "onboard_error",
    "realistic_errors",
    "simulate_sensor",
]

#: Earth's gravitational constant (WGS84), m^3/s^2.
GM_M3_S2 = 3.986004418e14
#: Earth's rotation rate (WGS84), rad/s.
EARTH_ROTATION_RAD_S = 7.292115e-5


@dataclass(frozen=True)
class OrbitSensorSpec:
    """Orbit, viewing geometry, detector and on-board error budget of a simulated scene.

    Parameters
    ----------
    name : str
        Label (``"spot5-strip1"``).
    altitude_m : float
        Orbit altitude above the equatorial radius, metres (circular orbit).
    inclination_deg : float
        Orbit inclination, degrees (> 90: retrograde, sun-synchronous).
    ascending : bool
        Whether the satellite flies northwards over the scene.
    centre_lon, centre_lat : float
        Scene centre, degrees; the image centre sees it at ``centre_h``.
    centre_h : float
        Height of the scene centre above the ellipsoid, metres.
    gsd_m : float
        Ground sample distance at nadir, metres (the across-track detector pitch is
        ``gsd_m / altitude_m`` radians); off nadir the ground pixels grow (Teo et al.'s strip 3
        at -14.8 degrees: 2.67 m against 2.52 m).
    shape : (int, int)
        ``(rows, cols)``.
    incidence_deg : float, optional
        Signed incidence angle at the scene centre (angle between the local vertical and the
        direction to the satellite), degrees; positive looks to the left of the flight
        direction (a positive roll). Overrides ``roll_deg``.
    roll_deg : float
        Off-nadir roll about the flight direction, degrees (used when ``incidence_deg`` is
        None); positive looks left.
    pitch_deg : float
        Pitch about the across-track axis, degrees; positive looks forward.
    line_period_s : float, optional
        Seconds per row; default ``gsd_m`` / ground speed of the nadir point (square pixels
        at nadir). Negative for a reverse scan (DigitalGlobe ``SCANDIRECTION Reverse``: the
        times fall as the row rises, row 0 is the last line acquired).
    reverse_scan : bool
        Scan backwards: the line period in use is ``-abs(line_period)`` (with the default
        period too). A negative ``line_period_s`` is a reverse scan without this flag.
    jitter_amplitude_rad : float
        Amplitude of the sinusoidal attitude jitter on roll, pitch and yaw, radians.
    jitter_frequency_hz : float
        Its frequency, Hz (random phase per axis).
    onboard_rmse_m : float
        Requested 2-D RMSE of the on-board geolocation over the scene (at ``centre_h``), m.
    onboard_drift_share : float
        Share of ``onboard_rmse_m**2`` due to the along-track drift (position and pitch
        rates: error growing with the distance from the image centre), in [0, 1).
    ephemeris_step_s : float
        Ephemeris sampling interval, seconds.
    attitude_rate_hz : float
        Attitude sampling rate, Hz.
    margin_s : float
        Time covered by ephemeris and attitude beyond each end of the image, seconds.
    epoch : str
        ISO-8601 UTC time of the scene centre.
    seed : int
        Seed of the jitter phases and the on-board errors.
    onboard_errors : {"realistic", "bias-drift"}
        The on-board error model (:data:`~geoblock.simulate.onboard.ONBOARD_ERRORS`):
        ``"realistic"`` adds the attitude wander, the look-angle error and the orbital-period
        ephemeris error below to the biases and drifts; ``"bias-drift"`` is biases and
        linear drifts only (the simulator before issue 27, bit for bit for a seed).
    wander_rms_rad : (float, float, float)
        Attitude wander of the true model: RMS of its departure from a cubic in time over
        the image span, roll/pitch/yaw, radians (default: :data:`~geoblock.simulate.
        onboard.WANDER_SPOT5`, measured on ``SPOT5.DIM``). Images spanning fewer than 5
        attitude samples get none.
    wander_slope : float
        Its power-law spectral slope (PSD ~ f**-slope).
    wander_band_hz : (float, float)
        Its band, Hz.
    look_error_rad : (float, float)
        RMS of the true model's look-angle error over the swath, along and across track,
        radians (Legendre degrees 4 and 5 across the swath; default the SPOT-5 look-angle
        table's departure from a cubic, :data:`~geoblock.simulate.onboard.
        LOOK_ERROR_SPOT5_PX` times the table's 6.011 urad detector pitch).
    ephemeris_rms_m : (float, float, float)
        RMS of the on-board ephemeris error at the orbital period, along, across, radial,
        metres (default :data:`~geoblock.simulate.onboard.EPHEMERIS_SPOT5_DIODE`).
    """

    name: str
    altitude_m: float
    inclination_deg: float
    ascending: bool
    centre_lon: float
    centre_lat: float
    gsd_m: float
    shape: tuple[int, int]
    incidence_deg: float | None = None
    roll_deg: float = 0.0
    pitch_deg: float = 0.0
    centre_h: float = 0.0
    line_period_s: float | None = None
    reverse_scan: bool = False
    jitter_amplitude_rad: float = 0.0
    jitter_frequency_hz: float = 1.0
    onboard_rmse_m: float = 20.0
    onboard_drift_share: float = 0.1
    ephemeris_step_s: float = 4.0
    attitude_rate_hz: float = 8.0
    margin_s: float = 12.0
    epoch: str = "2003-06-21T02:30:00Z"
    seed: int = 0
    onboard_errors: str = "realistic"
    wander_rms_rad: tuple[float, float, float] = _onboard.WANDER_SPOT5.rms_rad
    wander_slope: float = _onboard.WANDER_SPOT5.slope
    wander_band_hz: tuple[float, float] = _onboard.WANDER_SPOT5.band_hz
    look_error_rad: tuple[float, float] = (
        _onboard.LOOK_ERROR_SPOT5_PX[0] * _onboard.SPOT5_HRG_IFOV_RAD,
        _onboard.LOOK_ERROR_SPOT5_PX[1] * _onboard.SPOT5_HRG_IFOV_RAD)
    ephemeris_rms_m: tuple[float, float, float] = _onboard.EPHEMERIS_SPOT5_DIODE

    def __post_init__(self) -> None:
        def need(ok: bool, field: str, message: str) -> None:
            if not ok:
                raise GeoblockError(f"OrbitSensorSpec.{field}: {message} "
                                    f"(got {getattr(self, field)!r})")

        need(self.altitude_m > 100e3, "altitude_m", "must be > 100 km")
        need(0 < self.inclination_deg < 180, "inclination_deg", "must be in (0, 180)")
        lim = min(self.inclination_deg, 180 - self.inclination_deg)
        need(abs(self.centre_lat) < lim, "centre_lat",
             f"an orbit inclined {self.inclination_deg} deg does not fly over |lat| >= {lim}")
        need(self.gsd_m > 0, "gsd_m", "must be > 0")
        need(len(self.shape) == 2 and min(self.shape) >= 2, "shape", "must be (rows, cols) >= 2")
        need(self.line_period_s is None or (math.isfinite(self.line_period_s)
                                            and self.line_period_s != 0), "line_period_s",
             "must be finite and non-zero (negative: a reverse scan)")
        need(self.incidence_deg is None or abs(self.incidence_deg) < 60, "incidence_deg",
             "must be within +-60 degrees")
        need(abs(self.roll_deg) < 45 and abs(self.pitch_deg) < 45, "roll_deg",
             "roll and pitch must be within +-45 degrees")
        need(self.jitter_amplitude_rad >= 0 and self.jitter_frequency_hz > 0,
             "jitter_amplitude_rad", "jitter amplitude must be >= 0 and frequency > 0")
        need(self.onboard_rmse_m >= 0, "onboard_rmse_m", "must be >= 0")
        need(0 <= self.onboard_drift_share < 1, "onboard_drift_share", "must be in [0, 1)")
        need(self.ephemeris_step_s > 0 and self.attitude_rate_hz > 0 and self.margin_s > 0,
             "ephemeris_step_s", "sampling steps and margin must be > 0")
        need(self.onboard_errors in ONBOARD_ERRORS, "onboard_errors",
             f"must be one of {', '.join(ONBOARD_ERRORS)}")

        def sizes(field: str, n: int) -> None:
            value = getattr(self, field)
            need(isinstance(value, tuple) and len(value) == n
                 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                         and math.isfinite(v) and v >= 0 for v in value),
                 field, f"must be {n} finite sizes >= 0")

        sizes("wander_rms_rad", 3)
        sizes("look_error_rad", 2)
        sizes("ephemeris_rms_m", 3)
        try:
            WanderSpectrum(self.wander_rms_rad, self.wander_slope, self.wander_band_hz)
        except GeoblockError as exc:
            need(False, "wander_band_hz", str(exc))

    def replace(self, **changes: Any) -> OrbitSensorSpec:
        """A copy with some fields changed (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    def scaled(self, factor: float) -> OrbitSensorSpec:
        """The same footprint with ``factor`` times fewer rows and columns and a ``factor``
        times larger GSD (and line period): a small, fast variant of a scene."""
        rows, cols = self.shape
        return self.replace(
            name=f"{self.name}-small", gsd_m=self.gsd_m * factor,
            shape=(max(2, round(rows / factor)), max(2, round(cols / factor))),
            line_period_s=None if self.line_period_s is None else self.line_period_s * factor,
        )

    @property
    def wander(self) -> WanderSpectrum:
        """The attitude wander's :class:`~geoblock.simulate.onboard.WanderSpectrum`."""
        return WanderSpectrum(self.wander_rms_rad, self.wander_slope, self.wander_band_hz)

    def with_wander(self, spectrum: WanderSpectrum) -> OrbitSensorSpec:
        """A copy with the wander of ``spectrum`` (e.g. :data:`~geoblock.simulate.onboard.
        WANDER_DG`)."""
        return self.replace(wander_rms_rad=spectrum.rms_rad, wander_slope=spectrum.slope,
                            wander_band_hz=spectrum.band_hz)

    @property
    def orbital_period_s(self) -> float:
        """Period of the circular orbit, seconds."""
        return 2 * math.pi / self.mean_motion_rad_s

    @property
    def orbit_radius_m(self) -> float:
        """Radius of the circular orbit, metres."""
        return coords.WGS84_A + self.altitude_m

    @property
    def mean_motion_rad_s(self) -> float:
        """Angular rate of the satellite on its orbit, rad/s."""
        return math.sqrt(GM_M3_S2 / self.orbit_radius_m**3)

    @property
    def ground_speed_m_s(self) -> float:
        """Speed of the nadir point on a sphere of the equatorial radius (inertial), m/s."""
        return self.mean_motion_rad_s * coords.WGS84_A

    @property
    def line_period(self) -> float:
        """The line period in use, seconds: negative for a reverse scan."""
        period = (float(self.line_period_s) if self.line_period_s is not None
                  else self.gsd_m / self.ground_speed_m_s)
        return -abs(period) if self.reverse_scan else period

    @property
    def nominal_roll_rad(self) -> float:
        """Roll giving ``incidence_deg`` at the centre on a sphere (or ``roll_deg``), rad."""
        if self.incidence_deg is None:
            return math.radians(self.roll_deg)
        ratio = coords.WGS84_A / self.orbit_radius_m
        return math.asin(ratio * math.sin(math.radians(self.incidence_deg)))


class OnboardErrors(NamedTuple):
    """The errors of the on-board ephemeris and attitude (on-board minus true).

    Position in the orbital frame (along, across, radial up), attitude as rotations about the
    sensor axes (roll, pitch, yaw) right-multiplied to the true attitude; drifts per second of
    time from the image centre.
    """

    position_bias_m: Float64Array
    position_drift_m_s: Float64Array
    attitude_bias_rad: Float64Array
    attitude_drift_rad_s: Float64Array


class GroundError(NamedTuple):
    """On-board minus true ground positions over an image grid, metres."""

    row: Float64Array
    """(n, n) image rows of the grid."""
    col: Float64Array
    """(n, n) image columns."""
    de: Float64Array
    """(n, n) east error, metres."""
    dn: Float64Array
    """(n, n) north error, metres."""
    mean_e: float
    mean_n: float
    rmse_e: float
    rmse_n: float
    rmse: float
    """2-D RMSE, ``sqrt(rmse_e**2 + rmse_n**2)``."""


@dataclass(frozen=True)
class SimulatedSensor:
    """A simulated scene's sensor: the true model, the on-board model and how they differ."""

    spec: OrbitSensorSpec
    true_model: LinescanModel
    onboard_model: LinescanModel
    errors: OnboardErrors
    roll_rad: float
    """The roll used (giving the requested incidence at the centre)."""
    realistic: RealisticErrors | None = None
    """The wander, look-angle and orbital-period ephemeris errors drawn
    (``onboard_errors="realistic"``; None for ``"bias-drift"``)."""

    def onboard_error(self, n: int = 9) -> GroundError:
        """:func:`onboard_error` of this scene at the scene centre's height."""
        return onboard_error(self.true_model, self.onboard_model, n=n, h=self.spec.centre_h)


# ================================================================================ orbit
def _orbit_ecef(spec: OrbitSensorSpec, t: np.ndarray, u0: float,
                raan: float) -> tuple[Float64Array, Float64Array]:
    """ECEF positions (N, 3) and Earth-fixed velocities (N, 3) of the circular orbit at t."""
    r, n = spec.orbit_radius_m, spec.mean_motion_rad_s
    inc = math.radians(spec.inclination_deg)
    u = u0 + n * t
    cu, su = np.cos(u), np.sin(u)
    co, so = math.cos(raan), math.sin(raan)
    ci, si = math.cos(inc), math.sin(inc)
    # inertial frame coinciding with ECEF at t = 0
    p_i = r * np.stack([cu * co - su * ci * so, cu * so + su * ci * co, su * si], axis=-1)
    v_i = r * n * np.stack([-su * co - cu * ci * so, -su * so + cu * ci * co, cu * si], axis=-1)
    theta = EARTH_ROTATION_RAD_S * t
    c, s = np.cos(theta), np.sin(theta)

    def to_ecef(v: Float64Array) -> Float64Array:  # rotate by -theta about z
        return np.stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1], v[:, 2]], -1)

    p = to_ecef(p_i)
    omega = np.array([0.0, 0.0, EARTH_ROTATION_RAD_S])
    v = to_ecef(v_i) - np.cross(omega, p)
    return p, v


def _orbit_elements(spec: OrbitSensorSpec, lon: float, lat: float) -> tuple[float, float]:
    """Argument of latitude at t = 0 and RAAN putting the nadir at geocentric (lon, lat)."""
    inc = math.radians(spec.inclination_deg)
    phi = math.atan((1 - coords.WGS84_E2) * math.tan(math.radians(lat)))  # geocentric
    s = max(-1.0, min(1.0, math.sin(phi) / math.sin(inc)))
    u0 = math.asin(s)
    # ascending: d(lat)/dt > 0 <=> cos(u) sin(i) > 0
    if spec.ascending != (math.cos(u0) > 0):
        u0 = math.pi - u0
    raan = math.radians(lon) - math.atan2(math.sin(u0) * math.cos(inc), math.cos(u0))
    return u0, raan


def _sample_times(spec: OrbitSensorSpec) -> tuple[Float64Array, Float64Array]:
    """The ephemeris and attitude sampling times of a spec's models (as :func:`_build`)."""
    half = 0.5 * spec.shape[0] * abs(spec.line_period) + spec.margin_s
    n_eph = math.ceil(half / spec.ephemeris_step_s)
    step_att = 1.0 / spec.attitude_rate_hz
    n_att = math.ceil(half / step_att)
    return (spec.ephemeris_step_s * np.arange(-n_eph, n_eph + 1, dtype=np.float64),
            step_att * np.arange(-n_att, n_att + 1, dtype=np.float64))


def _build(spec: OrbitSensorSpec, nadir_lon: float, nadir_lat: float, roll: float,
           phases: np.ndarray, errors: OnboardErrors | None,
           extra: RealisticErrors | None = None) -> LinescanModel:
    """The model of the spec with the nadir at t = 0 over (nadir_lon, nadir_lat): the true
    model when ``errors`` is None (with the wander and look error of ``extra``), else the
    on-board model (with the orbital-period ephemeris error of ``extra``)."""
    rows, cols = spec.shape
    period = spec.line_period  # negative for a reverse scan
    half = 0.5 * rows * abs(period) + spec.margin_s
    n_eph = math.ceil(half / spec.ephemeris_step_s)
    t_eph = spec.ephemeris_step_s * np.arange(-n_eph, n_eph + 1, dtype=np.float64)
    u0, raan = _orbit_elements(spec, nadir_lon, nadir_lat)
    pos, vel = _orbit_ecef(spec, t_eph, u0, raan)
    step_att = 1.0 / spec.attitude_rate_hz
    n_att = math.ceil(half / step_att)
    t_att = step_att * np.arange(-n_att, n_att + 1, dtype=np.float64)
    pitch = math.radians(spec.pitch_deg)
    if errors is None:
        w = 2 * math.pi * spec.jitter_frequency_hz
        jit = spec.jitter_amplitude_rad * np.sin(w * t_att[:, None] + phases[None, :])
        angles = np.array([roll, pitch, 0.0]) + jit
        if extra is not None:
            angles = angles + extra.wander_rad
        r_att = rotation_xyz(angles[:, 0], angles[:, 1], angles[:, 2])
    else:
        err_pos = errors.position_bias_m + t_eph[:, None] * errors.position_drift_m_s
        m_orb = orbital_frame(pos, vel)
        err_pos = err_pos * np.array([1.0, 1.0, -1.0])  # radial up = -z_o
        pos = pos + np.einsum("nij,nj->ni", m_orb, err_pos)
        vel = vel + np.einsum("nij,j->ni", m_orb, errors.position_drift_m_s * [1.0, 1.0, -1.0])
        if extra is not None:
            up = np.array([1.0, 1.0, -1.0])
            pos = pos + np.einsum("nij,nj->ni", m_orb, extra.ephemeris_error_m * up)
            vel = vel + np.einsum("nij,nj->ni", m_orb, extra.ephemeris_rate_m_s * up)
        err_att = errors.attitude_bias_rad + t_att[:, None] * errors.attitude_drift_rad_s
        r_att = rotation_xyz(roll, pitch, 0.0) @ rotation_xyz(
            err_att[:, 0], err_att[:, 1], err_att[:, 2])
    c = np.arange(cols) - (cols - 1) / 2.0
    if extra is not None and errors is None:
        look = LookDirections.from_tan_angles(
            extra.look_error_tan[:, 0], c * spec.gsd_m / spec.altitude_m
            + extra.look_error_tan[:, 1])
    else:
        look = _nominal_look(cols, spec.gsd_m, spec.altitude_m)
    return LinescanModel(
        (rows, cols), Ephemeris(t_eph, pos, vel),
        Attitude(t_att, matrix_to_quaternion(r_att), frame="orbital"), look,
        LineTimes((rows - 1) / 2.0, 0.0, period), epoch=spec.epoch,
    )


@functools.lru_cache(maxsize=16)
def _nominal_look(cols: int, gsd_m: float, altitude_m: float) -> LookDirections:
    """The error-free look directions of ``cols`` detectors: one frozen object shared by every
    model of the same detector (10^4 on-board models of a large block hold one table, not
    10^4 copies of 3000 x 3 vectors)."""
    c = np.arange(cols) - (cols - 1) / 2.0
    return LookDirections.from_tan_angles(np.zeros(cols), c * gsd_m / altitude_m)


def incidence_angle(model: LinescanModel, row: float, col: float, h: float = 0.0) -> float:
    """Signed incidence angle (degrees) at an image point: the angle between the local
    vertical and the direction to the satellite, positive when the satellite is to the right
    of the ground point looking along the flight direction (the sensor looks left)."""
    g = model.backproject(row, col, h)
    p_sat, v_sat, _ = model.sensor_state(row)
    ground = np.stack(coords.geodetic_to_ecef(*g), axis=-1)
    to_sat = p_sat - ground
    up = coords.enu_rotation(g.lon, g.lat)[2]
    angle = math.degrees(math.acos(float(np.dot(up, to_sat) / np.linalg.norm(to_sat))))
    # the satellite is to the right of the ground point when the track direction crossed
    # with the ground->satellite vector points down
    side = float(np.dot(np.cross(v_sat, to_sat), up))
    return angle if side < 0 else -angle


# ================================================================================ simulation
def _centred(spec: OrbitSensorSpec, phases: np.ndarray, extra: RealisticErrors | None = None
             ) -> tuple[LinescanModel, float, tuple[float, float]]:
    """The true model with the image centre on the scene centre and the requested incidence."""
    rows, cols = spec.shape
    rc, cc = (rows - 1) / 2.0, (cols - 1) / 2.0
    frame = coords.LocalFrame(spec.centre_lon, spec.centre_lat, spec.centre_h)
    roll = spec.nominal_roll_rad
    nadir = (spec.centre_lon, spec.centre_lat)
    model = None
    for _ in range(6):
        model = _build(spec, nadir[0], nadir[1], roll, phases, None, extra)
        g = model.backproject(rc, cc, spec.centre_h)
        e, n, _ = frame.from_geodetic(g.lon, g.lat, g.h)
        # move the nadir by the miss (the mapping is nearly a translation)
        shifted = frame.to_geodetic(-float(e), -float(n), 0.0)
        nadir = (nadir[0] + float(shifted.lon) - spec.centre_lon,
                 nadir[1] + float(shifted.lat) - spec.centre_lat)
        if spec.incidence_deg is not None and spec.incidence_deg != 0.0:
            got = incidence_angle(model, rc, cc, spec.centre_h)
            roll *= math.sin(math.radians(spec.incidence_deg)) / math.sin(math.radians(got))
        if math.hypot(float(e), float(n)) < 1e-3 * spec.gsd_m:
            break
    model = _build(spec, nadir[0], nadir[1], roll, phases, None, extra)
    return model, roll, nadir


def _with_errors(spec: OrbitSensorSpec, nadir: tuple[float, float], roll: float,
                 phases: np.ndarray, errors: OnboardErrors,
                 extra: RealisticErrors | None = None) -> LinescanModel:
    return _build(spec, nadir[0], nadir[1], roll, phases, errors, extra)


def realistic_errors(spec: OrbitSensorSpec) -> RealisticErrors:
    """The wander, look-angle and orbital-period ephemeris errors of a ``"realistic"`` spec.

    Drawn from their own stream (``numpy.random.SeedSequence([seed, 27])``), so that the
    biases, drifts and jitter phases are those of ``"bias-drift"`` for the same seed.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(spec.seed) % 2**63, 27]))
    t_eph, t_att = _sample_times(spec)
    rows, cols = spec.shape
    half_img = 0.5 * (rows - 1) * abs(spec.line_period)
    inside = int(np.count_nonzero(np.abs(t_att) <= half_img))
    if inside >= 5 and any(v > 0 for v in spec.wander_rms_rad):
        wander = _onboard.attitude_wander(t_att, (-half_img, half_img), spec.wander, rng)
    else:  # a cubic through fewer than 5 samples misses nothing
        wander = np.zeros((t_att.size, 3))
    look = (_onboard.look_error(cols, spec.look_error_rad, rng) if cols >= 6
            else np.zeros((cols, 2)))
    phases = rng.uniform(0.0, 2 * math.pi, 3)
    err, rate = _onboard.ephemeris_periodic(t_eph, spec.ephemeris_rms_m, spec.orbital_period_s,
                                            phases)
    return RealisticErrors(t_att, wander, look, t_eph, err, rate)


def simulate_sensor(spec: OrbitSensorSpec) -> SimulatedSensor:
    """The true and the on-board model of a spec (deterministic for ``spec.seed``).

    Parameters
    ----------
    spec : OrbitSensorSpec

    Returns
    -------
    SimulatedSensor
        ``true_model`` (parameters zero), ``onboard_model`` (parameters zero, erroneous
        ephemeris and attitude, ``location_accuracy_m`` the spec's ``onboard_rmse_m`` when
        > 0, so that its ``with_parameter_set("dg")`` needs no option) and the ``errors``
        applied.
    """
    rng = np.random.default_rng(spec.seed)
    phases = rng.uniform(0.0, 2 * math.pi, 3)
    extra = realistic_errors(spec) if spec.onboard_errors == "realistic" else None
    true_model, roll, nadir = _centred(spec, phases, extra)
    zero = np.zeros(3)
    # error shapes: biases of comparable ground effect, random directions; drift along track
    alt = spec.altitude_m
    pos_dir = rng.normal(size=3) * [1.0, 1.0, 0.3]
    att_dir = rng.normal(size=3) * np.array([1.0, 1.0, 0.3]) / alt
    drift_sign = rng.choice([-1.0, 1.0], size=2)
    half_s = 0.5 * spec.shape[0] * abs(spec.line_period)
    shape_bias = OnboardErrors(pos_dir, zero, att_dir, zero)
    # along-track position drift plus a pitch drift, 1 m at the image's ends
    shape_drift = OnboardErrors(zero, np.array([drift_sign[0], 0.0, 0.0]) * 0.5 / half_s, zero,
                                np.array([0.0, drift_sign[1], 0.0]) * 0.5 / half_s / alt)
    target = spec.onboard_rmse_m
    # the ground error is linear in the error sizes: e = e0 + k_b e_b + k_d e_d, with e0 the
    # error of error-free on-board data (the unobserved jitter)
    zero_errors = OnboardErrors(zero, zero, zero, zero)
    e_0 = _errors_of(spec, true_model,
                     _with_errors(spec, nadir, roll, phases, zero_errors, extra))
    e_b = _errors_of(spec, true_model,
                     _with_errors(spec, nadir, roll, phases, shape_bias, extra)) - e_0
    e_d = _errors_of(spec, true_model,
                     _with_errors(spec, nadir, roll, phases, shape_drift, extra)) - e_0

    def dot(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.mean(np.sum(a * b, axis=-1)))

    base = dot(e_0, e_0)
    if target**2 <= base:
        scale_b = scale_d = 0.0
    else:
        scale_d = math.sqrt(spec.onboard_drift_share * (target**2 - base) / dot(e_d, e_d))
        # |e0 + k e_b + scale_d e_d|^2 = target^2, for k
        qa = dot(e_b, e_b)
        qb = dot(e_b, e_0) + scale_d * dot(e_b, e_d)
        qc = base + 2 * scale_d * dot(e_d, e_0) + scale_d**2 * dot(e_d, e_d) - target**2
        scale_b = (-qb + math.sqrt(qb * qb - qa * qc)) / qa
    errors = OnboardErrors(
        scale_b * shape_bias.position_bias_m, scale_d * shape_drift.position_drift_m_s,
        scale_b * shape_bias.attitude_bias_rad, scale_d * shape_drift.attitude_drift_rad_s,
    )
    onboard = _with_errors(spec, nadir, roll, phases, errors, extra)
    if spec.onboard_rmse_m > 0:  # the on-board data's stated accuracy: the "dg" set's sigmas
        onboard = onboard.replace(location_accuracy_m=spec.onboard_rmse_m)
    return SimulatedSensor(spec, true_model, onboard, errors, roll, extra)


def _errors_of(spec: OrbitSensorSpec, true: LinescanModel, onboard: LinescanModel) -> np.ndarray:
    err = onboard_error(true, onboard, h=spec.centre_h)
    return np.stack([err.de.ravel(), err.dn.ravel()], axis=-1)


def onboard_error(true: LinescanModel, onboard: LinescanModel, n: int = 9,
                  h: float = 0.0) -> GroundError:
    """Ground error of an on-board model against the true one over an image grid.

    Both models backproject an ``n x n`` grid of image points (pixel edge to pixel edge) at
    height ``h``; the error is the on-board point minus the true point in the true point's
    local east/north frame.

    Parameters
    ----------
    true, onboard : SensorModel
        Models of the same image.
    n : int
        Grid points per side.
    h : float
        Height above the ellipsoid, metres.

    Returns
    -------
    GroundError
    """
    r0, c0, r1, c1 = image_domain(true.shape)
    r, c = np.meshgrid(np.linspace(r0, r1, n), np.linspace(c0, c1, n),
                       indexing="ij")
    g_true = true.backproject(r, c, h)
    g_ob = onboard.backproject(r, c, h)
    de, dn, _ = coords.enu_offsets(*g_true, *g_ob)
    rmse_e, rmse_n = float(np.sqrt(np.mean(de**2))), float(np.sqrt(np.mean(dn**2)))
    return GroundError(r, c, de, dn, float(np.mean(de)), float(np.mean(dn)), rmse_e, rmse_n,
                       math.hypot(rmse_e, rmse_n))


# ================================================================================ presets
#: Teo et al.'s three SPOT-5 supermode strips over Taiwan (Table I: 2.52/2.52/2.67 m GSD,
#: incidence 5.21, 5.65, -14.76 deg, 24000 x 24000 px, 10-15 % overlap; Table II case I on-board
#: RMSE 2-D 33.6, 12.0 and 42.3 m). Orbit 832 km, 98.7 deg, descending (10:30 local time).
#: Realistic on-board errors (the default): the wander measured on ``SPOT5.DIM``
#: (:data:`~geoblock.simulate.onboard.WANDER_SPOT5`), its look-angle table's departure from a
#: cubic (as an angle: the supermode's 2.5 m pixels come from the 5 m detectors), DIODE's
#: ephemeris accuracy (:data:`~geoblock.simulate.onboard.EPHEMERIS_SPOT5_DIODE`).
SPOT5_STRIPS: tuple[OrbitSensorSpec, ...] = tuple(
    OrbitSensorSpec(
        name=f"spot5-strip{k + 1}", altitude_m=832e3, inclination_deg=98.7, ascending=False,
        centre_lon=lon, centre_lat=23.85, gsd_m=2.5, shape=(24000, 24000),
        incidence_deg=inc, jitter_amplitude_rad=5e-7, jitter_frequency_hz=1.0,
        onboard_rmse_m=rmse, onboard_drift_share=0.1, epoch=epoch, seed=k + 1,
    )
    for k, (lon, inc, rmse, epoch) in enumerate([
        (120.45, 5.2, 33.6, "2003-06-21T02:40:00Z"),
        (120.96, 5.7, 12.0, "2003-05-31T02:40:00Z"),
        (121.47, -14.8, 42.3, "2003-07-01T02:40:00Z"),
    ])
)
#: QuickBird basic imagery like Aguilar et al.'s (0.62 m GSD, 450 km, 97.2 deg, 8 deg
#: off-nadir, ~17 x 17 km) over Almeria, Spain; on-board 2-D RMSE 15 m with a 40 % share of
#: along-track drift growing with the distance from the image centre. Realistic on-board errors:
#: the wander of the DigitalGlobe ATT records (:data:`~geoblock.simulate.onboard.WANDER_DG`),
#: SPOT-5's look-angle departure in pixels at QuickBird's detector pitch, the DG ISDs' stated
#: ephemeris accuracy (:data:`~geoblock.simulate.onboard.EPHEMERIS_DG`).
QUICKBIRD = OrbitSensorSpec(
    name="quickbird", altitude_m=450e3, inclination_deg=97.2, ascending=False,
    centre_lon=-2.45, centre_lat=36.83, gsd_m=0.62, shape=(27552, 27424), roll_deg=8.0,
    jitter_amplitude_rad=2e-7, jitter_frequency_hz=2.0, onboard_rmse_m=15.0,
    onboard_drift_share=0.4, ephemeris_step_s=2.0, attitude_rate_hz=16.0,
    epoch="2004-08-06T11:05:00Z", seed=11,
    look_error_rad=(_onboard.LOOK_ERROR_SPOT5_PX[0] * 0.62 / 450e3,
                    _onboard.LOOK_ERROR_SPOT5_PX[1] * 0.62 / 450e3),
    ephemeris_rms_m=_onboard.EPHEMERIS_DG,
).with_wander(_onboard.WANDER_DG)
#: SPOT-1A-like (Chen & Lee): 10 m GSD, 6000 x 6000 px, 1.5 ms line period, 832 km,
#: 98.7 deg; on-board 2-D RMSE 30 m. Realistic on-board errors: the wander of the SPOT 1-4
#: records (:data:`~geoblock.simulate.onboard.WANDER_SPOT1_4`), SPOT-5's look-angle departure in
#: pixels at the 10 m detector pitch, SPOT-4 DIODE's ephemeris accuracy (SPOT 1 had no on-board
#: navigator: :data:`~geoblock.simulate.onboard.EPHEMERIS_SPOT4_DIODE` is a lower bound).
SPOT1A = OrbitSensorSpec(
    name="spot1a", altitude_m=832e3, inclination_deg=98.7, ascending=False,
    centre_lon=120.95, centre_lat=24.1, gsd_m=10.0, shape=(6000, 6000), line_period_s=1.5e-3,
    incidence_deg=10.0, onboard_rmse_m=30.0, onboard_drift_share=0.1,
    epoch="1988-03-15T02:40:00Z", seed=21,
    look_error_rad=(_onboard.LOOK_ERROR_SPOT5_PX[0] * 10.0 / 832e3,
                    _onboard.LOOK_ERROR_SPOT5_PX[1] * 10.0 / 832e3),
    ephemeris_rms_m=_onboard.EPHEMERIS_SPOT4_DIODE,
).with_wander(_onboard.WANDER_SPOT1_4)
#: Small variants: 40x (SPOT-5: 600 x 600 px at 100 m), 40x (QuickBird: ~690 x 686 px at
#: 24.8 m) and 10x (SPOT-1A: 600 x 600 px at 100 m) fewer rows and columns, same footprints,
#: same on-board errors in time and angle (the same wander over the same seconds, so a smaller
#: fraction of a pixel).
SPOT5_STRIPS_SMALL: tuple[OrbitSensorSpec, ...] = tuple(s.scaled(40) for s in SPOT5_STRIPS)
QUICKBIRD_SMALL = QUICKBIRD.scaled(40)
SPOT1A_SMALL = SPOT1A.scaled(10)
#: A SPOT-like 20 m scene (SPOT 4 HRVIR / SPOT 5 HRG multispectral: 60 x 60 km, 3000 x 3000
#: px at nadir), 832 km, 98.7 deg, descending, over France; on-board 2-D RMSE 30 m with a 10 %
#: share of along-track drift and SPOT-5's realistic errors (wander, look-angle and DIODE
#: ephemeris errors, the look-angle error at the 20 m detector pitch). The sensor of the
#: large blocks (:mod:`geoblock.simulate.large`) and the ``continental-spot-100`` preset.
SPOT_HRG20 = OrbitSensorSpec(
    name="spot-hrg20", altitude_m=832e3, inclination_deg=98.7, ascending=False,
    centre_lon=2.5, centre_lat=46.5, gsd_m=20.0, shape=(3000, 3000), incidence_deg=0.0,
    jitter_amplitude_rad=5e-7, jitter_frequency_hz=1.0, onboard_rmse_m=30.0,
    onboard_drift_share=0.1, epoch="2005-07-01T10:30:00Z", seed=31,
    look_error_rad=(_onboard.LOOK_ERROR_SPOT5_PX[0] * 20.0 / 832e3,
                    _onboard.LOOK_ERROR_SPOT5_PX[1] * 20.0 / 832e3),
)
