"""RPC00B coefficients: the vendor rational polynomial model, GDAL's conventions.

Normalisation (GDAL ``alg/gdal_rpc.cpp``; RPC00B)::

    L = (lon - LONG_OFF) / LONG_SCALE      (lon - LONG_OFF wrapped into [-180, 180))
    P = (lat - LAT_OFF) / LAT_SCALE
    H = (h - HEIGHT_OFF) / HEIGHT_SCALE    (h: metres above the WGS84 ellipsoid)
    row = LINE_NUM(L, P, H) / LINE_DEN(L, P, H) * LINE_SCALE + LINE_OFF
    col = SAMP_NUM(L, P, H) / SAMP_DEN(L, P, H) * SAMP_SCALE + SAMP_OFF

with the 20 cubic terms in RPC00B order (:data:`TERMS`). ``row, col`` are RPC00B-native, which
is geoblock's convention: ``(0, 0)`` is the centre of the first pixel (GDAL's pixel/line adds
0.5). Readers convert other conventions (DIMAP's 1-based offsets) once, when reading.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from geoblock.errors import ModelFormatError

__all__ = ["GDAL_KEYS", "LIMITS", "TERMS", "Rpc00b", "evaluate_terms", "wrap_longitude"]

#: RPC00B term order (GDAL, NITF RPC00B, DigitalGlobe RPB, DIMAP v2 all use it)
TERMS: tuple[str, ...] = (
    "1", "L", "P", "H", "L*P", "L*H", "P*H", "L^2", "P^2", "H^2",
    "P*L*H", "L^3", "L*P^2", "L*H^2", "L^2*P", "P^3", "P*H^2", "L^2*H", "P^2*H", "H^3",
)

_SCALARS = (
    "line_off", "samp_off", "lat_off", "long_off", "height_off",
    "line_scale", "samp_scale", "lat_scale", "long_scale", "height_scale",
)
_POLYS = ("line_num", "line_den", "samp_num", "samp_den")
_OPTIONAL = ("min_long", "min_lat", "max_long", "max_lat", "err_bias", "err_rand")

#: ``ERR_BIAS``/``ERR_RAND`` value meaning "unknown" (GDAL metadata, RPB and _RPC.TXT writers)
UNKNOWN_ERROR = -1.0
#: largest image offset, scale or size, pixels (the largest real scene here has 135 312 rows)
MAX_PIXELS = 1e7
#: largest magnitude of a coefficient relative to the constant term of its ratio's
#: denominator (real RPCs: below 300), and in absolute value
MAX_COEFFICIENT = 1e10
MAX_COEFFICIENT_ABS = 1e12
#: smallest and largest ground sample distance, metres per pixel (a microscope, a weather
#: satellite's coarsest band), and the largest ratio of the largest to the smallest: a pixel's
#: aspect (up to ~5, oversampled pushbroom or SAR azimuth) times 1 / cos(incidence) (3.9 at
#: 75 degrees). Real RPCs here: 0.33 .. 5.5 m, anisotropy at most 1.42 (rpc_WV2.xml). A wrong
#: LAT/LONG/LINE/SAMP_SCALE (another field's value) stretches one axis: 1e3 let 2 000-14 000 km
#: footprints through; 20 none above 650 km (all 3 786 swaps of a scalar field's value into
#: another on the 43 shared RPC files)
MIN_GSD_M = 1e-3
MAX_GSD_M = 1e5
MAX_GSD_ANISOTROPY = 20.0
#: farthest the image box (LINE/SAMP_OFF +/- LINE/SAMP_SCALE) may map to ground from the
#: ground centre, in ground scales (LAT/LONG_SCALE), at HEIGHT_OFF: an RPC describes the image
#: over its ground box (real RPCs: at most 1.08, rpcm's rpc_WV2.xml; a crop in either
#: convention maps inside its scene's box)
MAX_IMAGE_BOX_GROUND_SCALES = 3.0
#: largest vendor accuracy, metres (NITF RPC00B's ERR_BIAS field holds at most 9999.99)
MAX_ERROR_M = 1e5

#: field -> (lowest, highest, unit) of what an RPC of the Earth can hold; for scales, the
#: smallest and largest magnitude (a scale may be negative: LAT_SCALE of PlanetScope files)
LIMITS: dict[str, tuple[float, float, str]] = {
    "lat_off": (-90.0, 90.0, "degrees"),
    "long_off": (-180.0, 360.0, "degrees (-180..180 or 0..360)"),
    "height_off": (-1e4, 1e5, "metres"),
    "line_off": (-MAX_PIXELS, MAX_PIXELS, "pixels"),
    "samp_off": (-MAX_PIXELS, MAX_PIXELS, "pixels"),
    "lat_scale": (1e-7, 90.0, "degrees"),
    "long_scale": (1e-7, 180.0, "degrees"),
    "height_scale": (1e-2, 1e5, "metres"),
    "line_scale": (0.5, MAX_PIXELS, "pixels"),
    "samp_scale": (0.5, MAX_PIXELS, "pixels"),
    "min_lat": (-90.0, 90.0, "degrees"),
    "max_lat": (-90.0, 90.0, "degrees"),
    "min_long": (-360.0, 360.0, "degrees"),
    "max_long": (-360.0, 360.0, "degrees"),
    "err_bias": (0.0, MAX_ERROR_M, "metres"),
    "err_rand": (0.0, MAX_ERROR_M, "metres"),
}

#: field name -> GDAL ``RPC`` metadata-domain key
GDAL_KEYS: dict[str, str] = {
    **{name: name.upper() for name in _SCALARS},
    "line_num": "LINE_NUM_COEFF",
    "line_den": "LINE_DEN_COEFF",
    "samp_num": "SAMP_NUM_COEFF",
    "samp_den": "SAMP_DEN_COEFF",
    **{name: name.upper() for name in _OPTIONAL},
}


def _coefficients(value: Any, name: str, source: str) -> np.ndarray:
    arr = np.array(value, dtype=np.float64).ravel()
    if arr.shape != (20,) or not np.all(np.isfinite(arr)):
        raise ModelFormatError(
            f"{source}: {GDAL_KEYS[name]} must be 20 finite numbers, got {arr.size} "
            f"({'non-finite values' if arr.size == 20 else 'wrong count'})"
        )
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class Rpc00b:
    """The coefficients of one RPC00B model (immutable).

    Offsets are in geoblock's pixel-centre convention (as in RPC00B / GDAL metadata); angles
    are degrees and heights metres above the WGS84 ellipsoid. Optional fields are ``None``
    when the file does not give them (GDAL writes -1 for unknown ``ERR_BIAS``/``ERR_RAND``).

    Parameters
    ----------
    line_off, samp_off, lat_off, long_off, height_off : float
    line_scale, samp_scale, lat_scale, long_scale, height_scale : float
        Non-zero.
    line_num, line_den, samp_num, samp_den : array_like, (20,)
        Coefficients in RPC00B term order (:data:`TERMS`).
    min_long, min_lat, max_long, max_lat : float, optional
        Validity box, degrees.
    err_bias, err_rand : float, optional
        Vendor a-priori accuracy, metres (bias and random, 1 sigma, horizontal).
    source : str
        Where the coefficients came from (named in error messages; not part of the value).
    """

    line_off: float
    samp_off: float
    lat_off: float
    long_off: float
    height_off: float
    line_scale: float
    samp_scale: float
    lat_scale: float
    long_scale: float
    height_scale: float
    line_num: np.ndarray
    line_den: np.ndarray
    samp_num: np.ndarray
    samp_den: np.ndarray
    min_long: float | None = None
    min_lat: float | None = None
    max_long: float | None = None
    max_lat: float | None = None
    err_bias: float | None = None
    err_rand: float | None = None
    source: str = field(default="<rpc>", compare=False)

    def __post_init__(self) -> None:
        for name in _SCALARS:
            try:
                value = float(getattr(self, name))
            except (TypeError, ValueError):
                raise ModelFormatError(
                    f"{self.source}: {GDAL_KEYS[name]} is not a number: {getattr(self, name)!r}"
                ) from None
            if not math.isfinite(value):
                raise ModelFormatError(f"{self.source}: {GDAL_KEYS[name]} is not finite")
            if name.endswith("_scale") and value == 0.0:
                raise ModelFormatError(f"{self.source}: {GDAL_KEYS[name]} is zero")
            object.__setattr__(self, name, value)
        for name in _POLYS:
            object.__setattr__(self, name, _coefficients(getattr(self, name), name, self.source))
        for name in _OPTIONAL:
            value = getattr(self, name)
            if value is not None:
                try:
                    value = float(value)
                except (TypeError, ValueError):
                    raise ModelFormatError(
                        f"{self.source}: {GDAL_KEYS[name]} is not a number: {value!r}"
                    ) from None
                if not math.isfinite(value):
                    raise ModelFormatError(f"{self.source}: {GDAL_KEYS[name]} is not finite")
                if name.startswith("err_") and value < 0:
                    if value != UNKNOWN_ERROR:
                        raise ModelFormatError(
                            f"{self.source}: {GDAL_KEYS[name]} {value!r} is negative (an "
                            "accuracy in metres, or -1 for unknown)"
                        )
                    value = None  # -1 means unknown in GDAL metadata and RPC writers
                object.__setattr__(self, name, value)
        if self.line_den[0] == 0.0 or self.samp_den[0] == 0.0:
            raise ModelFormatError(
                f"{self.source}: the constant term of LINE_DEN_COEFF or SAMP_DEN_COEFF is zero"
            )

    # ------------------------------------------------------------------ plausibility
    def check_plausible(self) -> None:
        """Refuse values no real RPC can have (:data:`LIMITS`), naming the field and source.

        Construction checks only what the arithmetic needs (finite numbers, non-zero scales
        and constant denominator terms); this checks what is physically possible: offsets on
        the Earth and within :data:`MAX_PIXELS` of the image, scales of at most a hemisphere,
        100 km of height or :data:`MAX_PIXELS`, normalised coefficients of at most
        :data:`MAX_COEFFICIENT`, a ground sample distance at the ground centre within
        :data:`MIN_GSD_M` .. :data:`MAX_GSD_M` with an anisotropy below
        :data:`MAX_GSD_ANISOTROPY`, an image box whose centre and corners localise within
        :data:`MAX_IMAGE_BOX_GROUND_SCALES` ground scales of the ground centre, a non-empty
        validity box overlapping the ground box, and accuracies of at most :data:`MAX_ERROR_M`
        metres. The image box and the ground box need not have been normalised together: the
        RPC of a crop (s2p, rpcm, CARS) keeps the scene's ground normalisation and moves or
        re-normalises the image box. A zero of a denominator inside the box is no rule either
        (rpcm's SkySat L1A RPC and ASP's ``sample.RPB`` have one and are real). Every model
        (:class:`~geoblock_rpc.model.RpcModel`) and every reader calls it.

        Raises
        ------
        ModelFormatError
            The first implausible field, with its value and the accepted range.
        """
        for name, (lo, hi, unit) in LIMITS.items():
            value = getattr(self, name)
            if value is None:
                continue
            if name.endswith("_scale"):
                if not lo <= abs(value) <= hi:
                    raise ModelFormatError(
                        f"{self.source}: {GDAL_KEYS[name]} {value!r} is not a plausible scale: "
                        f"its magnitude must be in [{lo:g}, {hi:g}] {unit}"
                    )
            elif not lo <= value <= hi:
                raise ModelFormatError(
                    f"{self.source}: {GDAL_KEYS[name]} {value!r} is outside the physically "
                    f"possible range [{lo:g}, {hi:g}] {unit}"
                )
        for num, den in (("line_num", "line_den"), ("samp_num", "samp_den")):
            d0 = abs(float(getattr(self, den)[0]))
            for name in (num, den):
                coef = getattr(self, name)
                k = int(np.argmax(np.abs(coef)))
                if abs(coef[k]) > MAX_COEFFICIENT * d0 or abs(coef[k]) > MAX_COEFFICIENT_ABS:
                    raise ModelFormatError(
                        f"{self.source}: {GDAL_KEYS[name]}_{k + 1} ({TERMS[k]}) {coef[k]!r} is "
                        f"not a plausible coefficient: more than {MAX_COEFFICIENT:g} times the "
                        f"constant term of {GDAL_KEYS[den]} ({float(getattr(self, den)[0])!r}) "
                        f"or than {MAX_COEFFICIENT_ABS:g}"
                    )
        self._check_gsd()
        self._check_image_box()
        if self.has_validity_box:
            w, e, s, n = (float(v) for v in (self.min_long, self.max_long, self.min_lat,
                                             self.max_lat) if v is not None)
            if not (w < e <= w + 360.0 and s < n):
                raise ModelFormatError(f"{self.source}: the validity box MIN_LONG..MAX_LONG "
                                       f"{w!r}..{e!r}, MIN_LAT..MAX_LAT {s!r}..{n!r} is empty "
                                       "or spans more than 360 degrees")
            # the validity box and the ground box (LONG/LAT_OFF +/- LONG/LAT_SCALE) overlap
            dlon = abs((0.5 * (w + e) - self.long_off + 180.0) % 360.0 - 180.0)
            dlat = abs(0.5 * (s + n) - self.lat_off)
            if (dlon > 0.5 * (e - w) + abs(self.long_scale)
                    or dlat > 0.5 * (n - s) + abs(self.lat_scale)):
                raise ModelFormatError(
                    f"{self.source}: the validity box MIN_LONG..MAX_LONG {w!r}..{e!r}, "
                    f"MIN_LAT..MAX_LAT {s!r}..{n!r} does not overlap the ground box LONG_OFF "
                    f"{self.long_off!r} +/- LONG_SCALE {self.long_scale!r}, LAT_OFF "
                    f"{self.lat_off!r} +/- LAT_SCALE {self.lat_scale!r}")

    def ground_sample_distance(self) -> tuple[float, float]:
        """The smallest and largest ground sample distance at the ground centre, metres/pixel.

        The singular values' inverses of the ground -> image Jacobian (pixels per metre east and
        north on the ellipsoid at ``LONG_OFF, LAT_OFF, HEIGHT_OFF``). The ground normalisation
        is kept by crops (both conventions), so a crop's GSD is its scene's.

        Returns
        -------
        (float, float)
            Metres per pixel; ``inf`` where the Jacobian is singular, NaN where not finite.
        """
        jac = np.empty((2, 2))
        for i, (num, den, scale) in enumerate(((self.line_num, self.line_den, self.line_scale),
                                               (self.samp_num, self.samp_den, self.samp_scale))):
            ratio = num[0] / den[0]
            # d(ratio)/dL, d(ratio)/dP at L = P = H = 0, in pixels per degree
            jac[i, 0] = (num[1] - ratio * den[1]) / den[0] * scale / self.long_scale
            jac[i, 1] = (num[2] - ratio * den[2]) / den[0] * scale / self.lat_scale
        # metres per degree east and north on the WGS84 ellipsoid at the ground centre
        a, e2 = 6378137.0, 6.69437999014e-3
        s2 = math.sin(math.radians(self.lat_off)) ** 2
        n = a / math.sqrt(1.0 - e2 * s2)
        m = a * (1.0 - e2) / (1.0 - e2 * s2) ** 1.5
        east = math.radians(1.0) * (n + self.height_off) * math.cos(math.radians(self.lat_off))
        north = math.radians(1.0) * (m + self.height_off)
        with np.errstate(all="ignore"):
            jac = jac / np.array([east, north])
            if not np.all(np.isfinite(jac)):
                return math.nan, math.nan
            sv = np.linalg.svd(jac, compute_uv=False)
            return float(1.0 / sv[0]), float(1.0 / sv[1])

    def _check_gsd(self) -> None:
        small, large = self.ground_sample_distance()
        if not (MIN_GSD_M <= small and large <= MAX_GSD_M
                and large <= MAX_GSD_ANISOTROPY * small):
            raise ModelFormatError(
                f"{self.source}: the coefficients and scales give a ground sample distance of "
                f"{small:.3g} .. {large:.3g} m per pixel at the ground centre, not within "
                f"{MIN_GSD_M:g} .. {MAX_GSD_M:g} m with an anisotropy below "
                f"{MAX_GSD_ANISOTROPY:g}: LINE/SAMP_NUM_COEFF, _DEN_COEFF or the LINE/SAMP/LAT/"
                f"LONG_SCALE are wrong")

    def _check_image_box(self) -> None:
        """The centre and corners of the image box localise, at HEIGHT_OFF, within
        :data:`MAX_IMAGE_BOX_GROUND_SCALES` ground scales of the ground centre.

        A point where the localisation does not converge is left out (a zero of a denominator
        leaves pixels of real RPCs without a ground point: ASP's ``sample.RPB``), but one of the
        five at least must converge.
        """
        # numpy, not the compiled kernel: opening a model compiles nothing (the kernel's first
        # compilation takes 5 s; the tests hold the two to the same statuses and points)
        from geoblock_rpc.reference import localise

        limit = MAX_IMAGE_BOX_GROUND_SCALES
        u = np.array([0.0, -1.0, -1.0, 1.0, 1.0])
        v = np.array([0.0, -1.0, 1.0, -1.0, 1.0])
        row = self.line_off + u * abs(self.line_scale)
        col = self.samp_off + v * abs(self.samp_scale)
        h = np.full(5, self.height_off)
        lon, lat, status = localise(self, row, col, h, 1e-6, 1e-3, 60)
        found = status == 0
        with np.errstate(invalid="ignore"):
            dist = np.maximum(np.abs(wrap_longitude(lon - self.long_off) / self.long_scale),
                              np.abs((lat - self.lat_off) / self.lat_scale))
        far = found & ~(dist <= limit)
        if np.any(far) or not np.any(found):
            k = int(np.argmax(far)) if np.any(far) else 0
            where = "centre" if k == 0 else "corner"
            maps = (f"maps to ground {float(dist[k]):.3g} ground scales away" if np.any(far)
                    else "and its corners map to ground nowhere (the localisation does not "
                         "converge)")
            raise ModelFormatError(
                f"{self.source}: the image box {where} (row {row[k]:g}, col {col[k]:g}: LINE/"
                f"SAMP_OFF +/- LINE/SAMP_SCALE) {maps}, not within {limit:g} ground scales "
                f"(LAT/LONG_SCALE) of the ground centre (LAT_OFF, LONG_OFF) at HEIGHT_OFF: the "
                f"offsets, the scales or the coefficients are wrong")

    # ------------------------------------------------------------------ conversions
    @property
    def coefficients(self) -> np.ndarray:
        """(4, 20) ``[line_num, line_den, samp_num, samp_den]``."""
        return np.stack([self.line_num, self.line_den, self.samp_num, self.samp_den])

    @property
    def has_validity_box(self) -> bool:
        """Whether MIN/MAX_LONG/LAT are all given (and not GDAL's +-180/90 defaults)."""
        box = (self.min_long, self.min_lat, self.max_long, self.max_lat)
        return None not in box and box != (-180.0, -90.0, 180.0, 90.0)

    def replace(self, **changes: Any) -> Rpc00b:
        """A copy with some fields changed (e.g. ``line_off`` for a crop)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return Rpc00b(**values)

    @classmethod
    def from_gdal(cls, metadata: Mapping[str, Any], source: str = "<rpc>") -> Rpc00b:
        """From GDAL ``RPC`` metadata-domain items (``rasterio`` ``RPC.to_gdal()`` output too).

        Numbers may carry unit suffixes (``"+015834.00 pixels"``) as in ``_RPC.TXT`` files;
        coefficient lists are 20 whitespace-separated numbers or sequences.
        """
        md = {str(k).upper(): v for k, v in metadata.items()}
        missing = [GDAL_KEYS[n] for n in _SCALARS + _POLYS if GDAL_KEYS[n] not in md]
        if missing:
            raise ModelFormatError(f"{source}: not an RPC00B model: missing {', '.join(missing)}")
        kwargs: dict[str, Any] = {"source": source}
        for name in _SCALARS + _OPTIONAL:
            key = GDAL_KEYS[name]
            if key in md:
                kwargs[name] = _number(md[key], key, source)
        for name in _POLYS:
            raw = md[GDAL_KEYS[name]]
            items = raw.split() if isinstance(raw, str) else list(raw)
            kwargs[name] = [_number(v, GDAL_KEYS[name], source) for v in items]
        return cls(**kwargs)

    def to_gdal(self) -> dict[str, str]:
        """GDAL ``RPC`` metadata-domain items (shortest round-tripping decimal text)."""
        out = {}
        for name in _SCALARS:
            out[GDAL_KEYS[name]] = repr(getattr(self, name))
        for name in _POLYS:
            out[GDAL_KEYS[name]] = " ".join(repr(float(v)) for v in getattr(self, name))
        for name in _OPTIONAL:
            value = getattr(self, name)
            if value is not None:
                out[GDAL_KEYS[name]] = repr(value)
            elif name.startswith("err_"):
                out[GDAL_KEYS[name]] = "-1"
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dictionary (field names as keys; ``None`` for absent optional fields)."""
        out: dict[str, Any] = {name: getattr(self, name) for name in _SCALARS + _OPTIONAL}
        for name in _POLYS:
            out[name] = [float(v) for v in getattr(self, name)]
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "<dict>") -> Rpc00b:
        """Inverse of :meth:`to_dict`."""
        unknown = set(data) - set(_SCALARS + _POLYS + _OPTIONAL)
        if unknown:
            raise ModelFormatError(f"{source}: unknown RPC fields {sorted(unknown)}")
        return cls(**dict(data), source=source)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Rpc00b):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(tuple(self.coefficients.ravel()) + (self.line_off, self.samp_off))


def _number(value: Any, key: str, source: str) -> float:
    if isinstance(value, int | float | np.number):
        return float(value)
    text = str(value).strip().split()
    try:
        return float(text[0])
    except (IndexError, ValueError):
        raise ModelFormatError(f"{source}: {key} is not a number: {value!r}") from None


def wrap_longitude(d: np.ndarray) -> np.ndarray:
    """Longitude differences (degrees) wrapped to [-180, 180)."""
    return (d + 180.0) % 360.0 - 180.0


def evaluate_terms(l: np.ndarray, p: np.ndarray, h: np.ndarray) -> np.ndarray:  # noqa: E741
    """The 20 RPC00B terms of normalised coordinates, (*S, 20), in :data:`TERMS` order."""
    return np.stack(
        [
            np.ones_like(l), l, p, h, l * p, l * h, p * h, l * l, p * p, h * h,
            p * l * h, l**3, l * p * p, l * h * h, l * l * p, p**3, p * h * h, l * l * h,
            p * p * h, h**3,
        ],
        axis=-1,
    )
