"""On-board errors as real satellites have them: measured from real products, then simulated.

A simulated scene (:func:`geoblock.simulate.sensors.simulate_sensor`) has a *true* model and an
*on-board* model. With ``onboard_errors="bias-drift"`` they differ by biases and linear drifts
of the ephemeris and the attitude only: exactly the form of the ``"dg"`` correction, which
nine GCPs then remove everywhere. Real on-board data are not like that. With
``onboard_errors="realistic"`` (the default) three more components are drawn, each seeded,
each with its source and its size:

**Attitude wander** (:func:`attitude_wander`, on the true model; the on-board attitude does not
know it). A band-limited Gaussian process per axis (roll, pitch, yaw) with a power-law
spectrum ``PSD(f) ~ f**-slope`` for ``band_hz[0] <= f <= band_hz[1]``, synthesised on the
attitude sampling grid, minus its least-squares cubic in time over the image span, scaled so
that its RMS over the image span is ``rms_rad``. The sizes and slopes are *measured*
(:func:`measure_attitude_record`) on the real attitude records in ``../shared/data``: the
departure of each record from a cubic in time over the image's time span
(:data:`WANDER_DG`, :data:`WANDER_SPOT5`, :data:`WANDER_SPOT1_4`,
:data:`WANDER_PLEIADES`; ``tests/simulate/
test_onboard_measured.py`` re-measures them and fails when a constant drifts from its source).

**Interior orientation** (:func:`look_error`, on the true model). A smooth across- and
along-track look-angle error over the swath (focal-plane distortion, CCD misalignment):
Legendre polynomials of degree 4 and 5 in the normalised column (orthogonal to a cubic,
which is what the SPOT-5 look-angle table departs from a cubic by: it is a quintic), seeded
mix, scaled to ``look_error_rad`` RMS. Size: the departure of ``SPOT5.DIM``'s ``PSI_X`` /
``PSI_Y`` table from a cubic (:data:`LOOK_ERROR_SPOT5_PX`).

**Ephemeris at the orbital period** (:func:`ephemeris_periodic`, on the on-board model).
Along-track, across-track and radial sinusoids of the orbital period with seeded phases and
the RMS ``ephemeris_rms_m`` (amplitude ``sqrt(2)`` times it), beside the biases and drifts.
Sizes: the on-board orbit accuracy the products state (:data:`EPHEMERIS_DG`,
:data:`EPHEMERIS_SPOT4_DIODE`, :data:`EPHEMERIS_SPOT5_DIODE`). Within one scene (seconds of a
~100 minute orbit) such an error is a bias and a drift; between scenes of a block it is not.

The biases and drifts are then scaled as before, so that the on-board geolocation error
still has the requested RMSE (``onboard_rmse_m``).

Measurement functions take arrays (no file reading here: ``benchmarks/bench_onboard.py`` and
the test open the real products through :func:`geoblock.io.open_model`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from geoblock.errors import GeoblockError
from geoblock.models.linescan.rotations import quaternion_to_matrix
from geoblock.typing import ArrayLike, Float64Array

__all__ = [
    "EPHEMERIS_DG",
    "EPHEMERIS_SPOT4_DIODE",
    "EPHEMERIS_SPOT5_DIODE",
    "LOOK_ERROR_SPOT5_PX",
    "ONBOARD_ERRORS",
    "SPLINE_TOLERANCE_PX",
    "SPOT5_HRG_IFOV_RAD",
    "WANDER_DG",
    "WANDER_PLEIADES",
    "WANDER_SPOT1_4",
    "WANDER_SPOT5",
    "AttitudeRecord",
    "RealisticErrors",
    "WanderSpectrum",
    "attitude_wander",
    "body_angles",
    "departure_from_cubic",
    "ephemeris_periodic",
    "fit_power_law",
    "look_departure",
    "look_error",
    "measure_attitude_record",
    "periodogram",
    "spline_spacing",
]

#: The on-board error models of :class:`~geoblock.simulate.sensors.OrbitSensorSpec`:
#: ``"realistic"`` (biases and drifts plus attitude wander, interior orientation and
#: orbital-period ephemeris errors) and ``"bias-drift"`` (biases and linear drifts only, the
#: simulator before issue 27, bit for bit).
ONBOARD_ERRORS = ("realistic", "bias-drift")

#: The image-space tolerance of :func:`spline_spacing`, pixels (RMS).
SPLINE_TOLERANCE_PX = 0.01


@dataclass(frozen=True)
class WanderSpectrum:
    """A band-limited power-law attitude wander.

    Parameters
    ----------
    rms_rad : (float, float, float)
        RMS of the departure from a cubic in time over the image span, roll, pitch, yaw
        (rotations about the sensor's along-track x, across-track y and boresight z axes),
        radians.
    slope : float
        Spectral slope: the power spectral density goes as ``f**-slope``.
    band_hz : (float, float)
        Lowest and highest frequency with power, Hz (the highest: the Nyquist frequency of
        the records measured).
    source : str
        Where the numbers come from.
    """

    rms_rad: tuple[float, float, float]
    slope: float
    band_hz: tuple[float, float]
    source: str = ""

    def __post_init__(self) -> None:
        if len(self.rms_rad) != 3 or not all(math.isfinite(v) and v >= 0 for v in self.rms_rad):
            raise GeoblockError(f"WanderSpectrum.rms_rad: three finite values >= 0 (roll, "
                                f"pitch, yaw), got {self.rms_rad!r}")
        lo, hi = self.band_hz
        if not (0 < lo < hi and math.isfinite(hi)):
            raise GeoblockError(f"WanderSpectrum.band_hz: need 0 < low < high, got "
                                f"{self.band_hz!r}")
        if not (math.isfinite(self.slope) and 0 <= self.slope <= 6):
            raise GeoblockError(f"WanderSpectrum.slope: must be in [0, 6], got {self.slope!r}")


# ============================================================================ measured constants
# Every number below is re-measured from its source by tests/simulate/test_onboard_measured.py
# (skipped when ../shared/data is absent) and printed by benchmarks/bench_onboard.py.

#: DigitalGlobe ATT records (50 Hz) of the 8 DG ISDs in ``../shared/data`` (rpcm
#: ``rpc_WV1.xml``, ``rpc_WV3.xml``; ASP ``wv_test1/2.xml``, ``dg_example1/2/3.xml``;
#: COSI-Corr3D ``WV1.XML``): quadratic mean over the records of the RMS departure from a cubic
#: over each image's span (1.0-2.3 s), roll/pitch/yaw; the median spectral slope (roll and
#: pitch periodograms above 1.5 / span); up to the records' Nyquist frequency, 25 Hz.
WANDER_DG = WanderSpectrum(
    rms_rad=(6.28e-8, 1.03e-7, 7.30e-8), slope=3.29, band_hz=(0.05, 25.0),
    source="8 DigitalGlobe ATT records in ../shared/data (WV01, WV02, WV03; 50 Hz)")
#: SPOT-5 HRG ``SPOT5.DIM`` (COSI-Corr3D; corrected attitudes, 8 Hz, 9.0 s image): the RMS
#: departure from a cubic, roll/pitch/yaw; the slope; up to 4 Hz.
WANDER_SPOT5 = WanderSpectrum(
    rms_rad=(8.86e-8, 4.34e-7, 1.26e-7), slope=2.11, band_hz=(0.05, 4.0),
    source="SPOT5.DIM corrected attitudes (COSI-Corr3D test data, 8 Hz)")
#: SPOT 1-4 ``SPOT1..4.DIM`` (COSI-Corr3D; 7.94 Hz, 9.0 s images): quadratic mean of the RMS
#: departures from a cubic, the median slope; up to the Nyquist frequency, 3.97 Hz.
WANDER_SPOT1_4 = WanderSpectrum(
    rms_rad=(6.01e-7, 3.23e-6, 6.53e-7), slope=4.41, band_hz=(0.05, 3.97),
    source="SPOT1..4.DIM attitudes (COSI-Corr3D test data, 7.94 Hz)")
#: Pleiades 1B ``PHRDIMAP_*.XML`` (shareloc; ``Accurate_Attitudes``, inertial, 8 Hz, the
#: whole 3-4 s records): quadratic mean of the RMS departures from a cubic, the median slope.
#: The products' own attitude model is a cubic polynomial, which misses this.
WANDER_PLEIADES = WanderSpectrum(
    rms_rad=(8.75e-7, 7.20e-7, 6.28e-7), slope=4.70, band_hz=(0.05, 4.0),
    source="PHRDIMAP_*.XML Accurate_Attitudes (shareloc test data, 8 Hz)")

#: SPOT-5 HRG ``SPOT5.DIM`` look-angle table (12000 detectors): RMS departure of ``PSI_X``
#: (along track) and ``PSI_Y`` (across track) from a least-squares cubic in the column, in
#: pixels of the table's own detector pitch (6.01 urad): the table is a quintic (it departs
#: from a quintic by < 1e-4 px). Maxima: 0.056 and 0.160 px.
LOOK_ERROR_SPOT5_PX = (0.0126, 0.0410)
#: The IFOV of the ``SPOT5.DIM`` look-angle table (median detector pitch), radians.
SPOT5_HRG_IFOV_RAD = 6.011e-6

#: DigitalGlobe ephemeris accuracy the ISDs state: the square root of the mean of the diagonal
#: of the EPH position covariances of the 8 DG ISDs in ``../shared/data`` (metres; the same on
#: the three axes: the records give it in ECEF), as (along, across, radial) RMS.
EPHEMERIS_DG = (0.0547, 0.0547, 0.0547)
#: SPOT-4's on-board DORIS navigator DIODE, RMS after a year in flight (CNES, DORIS mail 0075,
#: 1999): along track 4.0 m, across track 3.0 m, radial 2.7 m.
EPHEMERIS_SPOT4_DIODE = (4.0, 3.0, 2.7)
#: SPOT-5's DIODE: "an order of magnitude" better than SPOT-4's (Tournier, Berthias, Jayles
#: et al., CNES: "Orbit and time on-board computation: from the current SPOT4 solution to
#: GNSS2 needs"), i.e. :data:`EPHEMERIS_SPOT4_DIODE` / 10.
EPHEMERIS_SPOT5_DIODE = (0.40, 0.30, 0.27)


# ============================================================================ simulation
class RealisticErrors(NamedTuple):
    """The components a ``"realistic"`` scene adds to the biases and drifts.

    Attributes
    ----------
    attitude_time_s : ndarray, (n,)
        The attitude sampling times (seconds from the scene centre).
    wander_rad : ndarray, (n, 3)
        The attitude wander of the true model (roll, pitch, yaw), radians.
    look_error_tan : ndarray, (cols, 2)
        The true model's look tangents minus the on-board model's (along, across).
    ephemeris_time_s : ndarray, (m,)
        The ephemeris sampling times.
    ephemeris_error_m : ndarray, (m, 3)
        The on-board ephemeris minus the true one from the orbital-period term, in the
        orbital frame (along, across, radial up), metres.
    ephemeris_rate_m_s : ndarray, (m, 3)
        Its time derivative, m/s.
    """

    attitude_time_s: Float64Array
    wander_rad: Float64Array
    look_error_tan: Float64Array
    ephemeris_time_s: Float64Array
    ephemeris_error_m: Float64Array
    ephemeris_rate_m_s: Float64Array


def _cubic_residual(t: np.ndarray, values: np.ndarray, fit: np.ndarray) -> np.ndarray:
    """``values`` minus their least-squares cubic in ``t`` fitted on the rows ``fit``."""
    mid = 0.5 * (t[fit].max() + t[fit].min())
    half = max(0.5 * (t[fit].max() - t[fit].min()), 1e-300)
    tau = (t - mid) / half
    basis = np.vander(tau, 4)
    coef = np.linalg.lstsq(basis[fit], values[fit], rcond=None)[0]
    return values - basis @ coef


def attitude_wander(time_s: ArrayLike, span_s: tuple[float, float], spectrum: WanderSpectrum,
                    rng: np.random.Generator) -> Float64Array:
    """A seeded band-limited power-law attitude wander on a uniform time grid.

    Parameters
    ----------
    time_s : array_like, (n,)
        Uniformly spaced sample times, seconds (the attitude grid), n >= 8.
    span_s : (float, float)
        The image's time span; the wander's cubic over it is removed and its RMS over it is
        ``spectrum.rms_rad`` (at least 5 samples must fall in it).
    spectrum : WanderSpectrum
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, (n, 3)
        Roll, pitch and yaw, radians.
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = t.size
    inside = (t >= span_s[0]) & (t <= span_s[1])
    if n < 8 or int(inside.sum()) < 5:
        raise GeoblockError(f"attitude_wander: need >= 8 samples, >= 5 in the span {span_s}, "
                            f"got {n} and {int(inside.sum())}")
    dt = (t[-1] - t[0]) / (n - 1)
    freq = np.fft.rfftfreq(n, dt)
    lo, hi = spectrum.band_hz
    band = (freq >= lo) & (freq <= hi)
    amp = np.zeros_like(freq)
    amp[band] = freq[band] ** (-0.5 * spectrum.slope)
    white = rng.normal(size=(n, 3))
    series = np.fft.irfft(np.fft.rfft(white, axis=0) * amp[:, None], n=n, axis=0)
    series = _cubic_residual(t, series, inside)
    rms = np.sqrt(np.mean(series[inside] ** 2, axis=0))
    scale = np.where(rms > 0, np.asarray(spectrum.rms_rad) / np.where(rms > 0, rms, 1.0), 0.0)
    out: Float64Array = series * scale
    return out


def _legendre45(x: np.ndarray) -> np.ndarray:
    """Legendre polynomials P4, P5 at x, (n, 2)."""
    p4 = (35 * x**4 - 30 * x**2 + 3) / 8
    p5 = (63 * x**5 - 70 * x**3 + 15 * x) / 8
    return np.stack([p4, p5], axis=-1)


def look_error(cols: int, rms_rad: tuple[float, float], rng: np.random.Generator
               ) -> Float64Array:
    """A seeded smooth look-angle error over the swath, orthogonal to a cubic in the column.

    Parameters
    ----------
    cols : int
        Detectors (>= 6).
    rms_rad : (float, float)
        RMS over the detectors of the along-track and across-track error, radians.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, (cols, 2)
        Along- and across-track tangent errors per detector (small angles, radians): each a
        random mix of the Legendre polynomials of degree 4 and 5 in ``x = -1 ... 1`` across
        the swath, less its discrete least-squares cubic, scaled to the RMS.
    """
    if cols < 6:
        raise GeoblockError(f"look_error: need >= 6 detectors, got {cols}")
    x = np.linspace(-1.0, 1.0, cols)
    mix = rng.normal(size=(2, 2))  # (P4, P5) weights per axis
    shapes = _legendre45(x) @ mix
    shapes = _cubic_residual(x, shapes, np.ones(cols, dtype=bool))
    rms = np.sqrt(np.mean(shapes**2, axis=0))
    out: Float64Array = shapes * (np.asarray(rms_rad) / rms)
    return out


def ephemeris_periodic(time_s: ArrayLike, rms_m: tuple[float, float, float], period_s: float,
                       phases: ArrayLike) -> tuple[Float64Array, Float64Array]:
    """Along-track, across-track and radial sinusoids of the orbital period.

    Parameters
    ----------
    time_s : array_like, (n,)
        Seconds from the scene centre.
    rms_m : (float, float, float)
        RMS of each component, metres (amplitude ``sqrt(2) * rms_m``).
    period_s : float
        The orbital period, seconds.
    phases : array_like, (3,)
        Phases, radians.

    Returns
    -------
    error : ndarray, (n, 3)
        Along, across, radial (up), metres.
    rate : ndarray, (n, 3)
        Their time derivatives, m/s.
    """
    t = np.asarray(time_s, dtype=np.float64)[:, None]
    w = 2 * math.pi / period_s
    amp = math.sqrt(2.0) * np.asarray(rms_m, dtype=np.float64)
    arg = w * t + np.asarray(phases, dtype=np.float64)
    return amp * np.sin(arg), amp * w * np.cos(arg)


# ============================================================================ measurement
def body_angles(quaternion: ArrayLike, reference: int | None = None) -> Float64Array:
    """Rotation vectors of each attitude relative to a reference sample, in body axes.

    Parameters
    ----------
    quaternion : array_like, (m, 4)
        ``(w, x, y, z)`` body -> frame quaternions (any frame: ECEF, inertial, orbital).
    reference : int, optional
        The reference sample (default the middle one).

    Returns
    -------
    ndarray, (m, 3)
        ``log(R_ref^T R(t))`` about the body's x (roll), y (pitch) and z (yaw) axes,
        radians. The frame's own smooth rotation (the orbit, the Earth) is a smooth function
        of time here, which the cubic of :func:`departure_from_cubic` takes out.
    """
    r = quaternion_to_matrix(np.asarray(quaternion, dtype=np.float64))
    ref = r[r.shape[0] // 2 if reference is None else reference]
    rel = np.einsum("ji,njk->nik", ref, r)
    cos = np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    k = np.where(theta < 1e-8, 0.5, theta / (2.0 * np.sin(np.maximum(theta, 1e-300))))
    out: Float64Array = k[:, None] * np.stack(
        [rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]],
        axis=-1)
    return out


def departure_from_cubic(time_s: ArrayLike, values: ArrayLike) -> Float64Array:
    """``values`` (n, ...) minus their least-squares cubic in time (n >= 5)."""
    t = np.asarray(time_s, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if t.size < 5:
        raise GeoblockError(f"departure_from_cubic: need >= 5 samples, got {t.size}")
    flat = v.reshape(t.size, -1)
    return _cubic_residual(t, flat, np.ones(t.size, dtype=bool)).reshape(v.shape)


def periodogram(time_s: ArrayLike, values: ArrayLike) -> tuple[Float64Array, Float64Array]:
    """One-sided power spectral density of uniformly sampled values (Hann window).

    Parameters
    ----------
    time_s : array_like, (n,)
        Uniform sample times, seconds.
    values : array_like, (n, k)

    Returns
    -------
    freq : ndarray, (n // 2 + 1,)
        Hz, from 0 to the Nyquist frequency ``1 / (2 dt)``, in steps of ``1 / (n dt)``.
    psd : ndarray, (n // 2 + 1, k)
        Units squared per Hz (the sum times the frequency step is the variance).
    """
    t = np.asarray(time_s, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64).reshape(t.size, -1)
    n = t.size
    dt = (t[-1] - t[0]) / (n - 1)
    win = np.hanning(n)
    spec = np.fft.rfft((v - v.mean(axis=0)) * win[:, None], axis=0)
    psd = np.abs(spec) ** 2 * dt / np.sum(win**2)
    psd[1:-1] *= 2.0
    return np.fft.rfftfreq(n, dt), psd


def fit_power_law(freq: ArrayLike, psd: ArrayLike, f_min: float) -> float:
    """The slope ``s`` of ``psd ~ f**-s``: least squares on the logarithms for f >= f_min."""
    f = np.asarray(freq, dtype=np.float64)
    p = np.asarray(psd, dtype=np.float64)
    use = (f >= f_min) & (p > 0)
    if use.sum() < 3:
        raise GeoblockError(f"fit_power_law: fewer than 3 positive bins above {f_min} Hz")
    return float(-np.polyfit(np.log(f[use]), np.log(p[use]), 1)[0])


def spline_spacing(time_s: ArrayLike, values_px: ArrayLike, line_period_s: float,
                   tolerance_px: float = SPLINE_TOLERANCE_PX, candidates: int = 200
                   ) -> tuple[float, float]:
    """The knot spacing (lines) a uniform cubic B-spline in time needs to represent a record.

    The spacings tried are ``candidates`` values from two sample intervals to the record's
    span (geometric); at each a least-squares cubic B-spline (uniform knots from the first
    sample, ``scipy.interpolate.make_lsq_spline``) is fitted to every column of
    ``values_px``. The answer is the largest spacing at and below which every spacing tried
    represents every column to ``tolerance_px`` RMS (the residual is not monotonic in the
    spacing: a lucky coarse spacing does not count).

    Parameters
    ----------
    time_s : array_like, (n,)
        Sample times, seconds, increasing.
    values_px : array_like, (n, k)
        The record in pixels (e.g. the departure from a cubic of roll and pitch over IFOV).
    line_period_s : float
        Seconds per line (its magnitude is used).
    tolerance_px : float
    candidates : int

    Returns
    -------
    spacing_lines : float
        The spacing; NaN when even two sample intervals do not reach the tolerance.
    residual_px : float
        The largest column RMS residual at that spacing (at two sample intervals when NaN).
    """
    from scipy.interpolate import make_lsq_spline

    t = np.asarray(time_s, dtype=np.float64)
    v = np.asarray(values_px, dtype=np.float64).reshape(t.size, -1)
    period = abs(float(line_period_s))
    dt = float(np.median(np.diff(t)))
    span = float(t[-1] - t[0])
    best, best_res, first_res = math.nan, math.nan, math.nan
    for h in np.geomspace(2.0 * dt, span, candidates):
        n_int = max(1, math.ceil(span / h - 1e-9))
        inner = t[0] + h * np.arange(1, n_int)
        end = t[0] + h * n_int
        knots = np.concatenate([[t[0]] * 4, inner, [max(end, t[-1])] * 4])
        try:
            spline = make_lsq_spline(t, v, knots, k=3)
        except (ValueError, np.linalg.LinAlgError):
            break  # Schoenberg-Whitney fails: too fine for the samples
        res = float(np.sqrt(np.mean((spline(t) - v) ** 2, axis=0)).max())
        if math.isnan(first_res):
            first_res = res
        if res > tolerance_px:
            break
        best, best_res = h / period, res
    return best, (best_res if not math.isnan(best) else first_res)


def look_departure(tangents: ArrayLike, degree: int = 3) -> Float64Array:
    """Look tangents (cols, k) minus their least-squares polynomial of ``degree`` in the
    normalised column (same units as the input)."""
    tan = np.asarray(tangents, dtype=np.float64)
    flat = tan.reshape(tan.shape[0], -1)
    x = np.linspace(-1.0, 1.0, tan.shape[0])
    basis = np.vander(x, degree + 1)
    coef = np.linalg.lstsq(basis, flat, rcond=None)[0]
    out: Float64Array = (flat - basis @ coef).reshape(tan.shape)
    return out


class AttitudeRecord(NamedTuple):
    """One real attitude record over its image's time span, measured
    (:func:`measure_attitude_record`)."""

    samples: int
    """Attitude samples within the image's span."""
    rate_hz: float
    """Sampling rate (1 / median interval), Hz; the Nyquist frequency is half of it."""
    span_s: float
    """Time from the first to the last sample used, seconds."""
    rms_rad: Float64Array
    """(3,) RMS departure from a cubic in time, roll/pitch/yaw, radians."""
    rms_px: Float64Array
    """(3,) the same in pixels: roll and pitch over the IFOV (across- and along-track
    pixels), yaw times the RMS distance of a column from the centre (``cols / sqrt(12)``)."""
    dominant_hz: Float64Array
    """(3,) the frequency of the periodogram's largest non-zero bin per axis, Hz."""
    slope: float
    """Power-law slope of the roll and pitch periodograms (mean), above 1.5 / span."""
    spline_lines: float
    """Knot spacing (lines) representing the roll and pitch departures to
    :data:`SPLINE_TOLERANCE_PX` (:func:`spline_spacing`; NaN: finer than two samples)."""
    spline_residual_px: float
    """The largest roll/pitch RMS residual at that spacing, pixels."""
    departure_rad: Float64Array
    """(n, 3) the departure itself."""
    time_s: Float64Array
    """(n,) its times."""


def measure_attitude_record(time_s: ArrayLike, quaternion: ArrayLike, span_s: tuple[float, float],
                            ifov_rad: float, cols: int, line_period_s: float) -> AttitudeRecord:
    """Measure an attitude record's departure from a cubic over an image's time span.

    Parameters
    ----------
    time_s : array_like, (m,)
        Attitude sample times, seconds.
    quaternion : array_like, (m, 4)
        ``(w, x, y, z)`` body -> frame quaternions (any frame: see :func:`body_angles`).
    span_s : (float, float)
        The image's first and last line times; the samples within it are used (>= 8).
    ifov_rad : float
        The angle between neighbouring detectors, radians.
    cols : int
        Image width (for the yaw in pixels).
    line_period_s : float
        Seconds per line.

    Returns
    -------
    AttitudeRecord
    """
    t = np.asarray(time_s, dtype=np.float64)
    q = np.asarray(quaternion, dtype=np.float64)
    lo, hi = min(span_s), max(span_s)
    use = (t >= lo) & (t <= hi)
    if use.sum() < 8:
        raise GeoblockError(f"measure_attitude_record: {int(use.sum())} attitude samples in "
                            f"the image span {lo:.3f} .. {hi:.3f} s, need >= 8")
    t, q = t[use], q[use]
    dep = departure_from_cubic(t, body_angles(q))
    rms = np.sqrt(np.mean(dep**2, axis=0))
    rms_px = np.array([rms[0] / ifov_rad, rms[1] / ifov_rad, rms[2] * cols / math.sqrt(12.0)])
    freq, psd = periodogram(t, dep)
    dominant = freq[1 + np.argmax(psd[1:], axis=0)]
    span = float(t[-1] - t[0])
    slope = 0.5 * (fit_power_law(freq, psd[:, 0], 1.5 / span)
                   + fit_power_law(freq, psd[:, 1], 1.5 / span))
    spacing, residual = spline_spacing(t, dep[:, :2] / ifov_rad, line_period_s)
    dt = float(np.median(np.diff(t)))
    return AttitudeRecord(int(t.size), 1.0 / dt, span, rms, rms_px, dominant, slope, spacing,
                          residual, dep, t)
