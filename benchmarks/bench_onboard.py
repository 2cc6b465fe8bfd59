"""Measure the real attitude records and look-angle tables the simulator's on-board errors
come from (issue 27): the table of docs/user-guide/simulation.md, "Realistic on-board errors".

Run: ``python benchmarks/bench_onboard.py [DATA_DIR]`` (default ``$GEOBLOCK_TEST_DATA`` or
``../shared/data``). Prints, per real record: sensor, sampling rate, image span, RMS
departure of roll/pitch/yaw from a cubic in time (urad and px), the dominant frequencies of
the departure's periodogram (with the Nyquist frequency), the power-law slope, and the knot
spacing (lines) at which a uniform cubic B-spline in time represents the roll and pitch
departure to 0.01 px RMS; then the SPOT look-angle tables' departure from a cubic, the DG
ephemeris covariances, the per-family constants, and the time to build each sensor preset
in both on-board error modes. Nothing is asserted here: ``tests/simulate/
test_onboard_measured.py`` checks the simulator's constants against the same measurement.

Records: every DigitalGlobe ISD (ATT, 50 Hz), SPOT 1-5 ``*.DIM`` (DIMAP v1 attitudes, 8 Hz)
and SPOT 6 ``SPOT6.XML`` (Quaternion_List) through :func:`geoblock.io.open_model` (the
model's attitude over the image's rows), and the two Pleiades ``PHRDIMAP_*.XML``, whose
model attitude is the product's cubic polynomial (no departure by construction): for them
the ``Accurate_Attitudes`` quaternions (inertial, TAI, 8 Hz), which geoblock's reader does
not use, are read here with ElementTree and measured over the whole record (4 s, the image
is 3.7 s).
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

DG = ("rpcm/test_rpc_files/rpc_WV1.xml", "rpcm/test_rpc_files/rpc_WV3.xml",
      "stereopipeline/tests/wv_test1.xml", "stereopipeline/tests/wv_test2.xml",
      "stereopipeline/tests/dg_example1.xml", "stereopipeline/tests/dg_example2.xml",
      "stereopipeline/tests/dg_example3.xml", "cosicorr3d/test_dataset/WV1.XML")
SPOT = tuple(f"cosicorr3d/test_dataset/SPOT{k}.DIM" for k in (1, 2, 3, 4, 5))
SPOT6 = ("cosicorr3d/test_dataset/SPOT6.XML",)
PLEIADES = ("shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML",
            "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML")
FAMILY = {**{f: "dg" for f in DG}, **{f: "spot1-4" for f in SPOT[:4]},
          SPOT[4]: "spot5", SPOT6[0]: "spot6", **{f: "pleiades" for f in PLEIADES}}


class Measured(NamedTuple):
    file: str
    sensor: str
    family: str
    record: Any  # geoblock.simulate.onboard.AttitudeRecord
    ifov_rad: float
    line_period_s: float


def data_dir(arg: str | None = None) -> Path:
    if arg:
        return Path(arg)
    env = os.environ.get("GEOBLOCK_TEST_DATA")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "shared" / "data"


def _image_span(model: Any) -> tuple[float, float]:
    lt = model.line_times
    rows = model.shape[0]
    t0 = lt.reference_time_s + (0 - lt.reference_row) * lt.line_period_s
    t1 = lt.reference_time_s + (rows - 1 - lt.reference_row) * lt.line_period_s
    return min(t0, t1), max(t0, t1)


def _ifov(model: Any) -> float:
    v = model.look.vectors
    return float(abs(np.median(np.diff(v[:, 1] / v[:, 2]))))


SENSOR = {DG[0]: "WV01", DG[1]: "WV03", DG[2]: "WV02", DG[3]: "WV02",
          DG[4]: "WV01 (anonymised)", DG[5]: "WV01 (anonymised)", DG[6]: "WV01 (anonymised)",
          DG[7]: "WV01 (reverse scan)", **{f: f"SPOT {k} HRV/HRG" for k, f in enumerate(SPOT, 1)},
          SPOT6[0]: "SPOT 6", PLEIADES[0]: "Pleiades 1B", PLEIADES[1]: "Pleiades 1B"}


def _pleiades_quaternions(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``Accurate_Attitudes`` quaternions of a PHRDIMAP (TAI seconds from the first)."""
    root = ET.parse(path).getroot()
    node = root.find(".//Accurate_Attitudes/Quaternion_List")
    if node is None:
        raise ValueError(f"{path}: no Accurate_Attitudes/Quaternion_List")
    times, quats = [], []
    for q in node.findall("Quaternion"):
        times.append(np.datetime64(q.findtext("TAI_TIME")))
        quats.append([float(x) for x in q.findtext("Q_VALUES", "").split()])
    t = np.array([(x - times[0]) / np.timedelta64(1, "ns") * 1e-9 for x in times])
    return t, np.array(quats)


def measure_all(root: Path) -> list[Measured]:
    """Measure every record (files that are absent are skipped)."""
    from geoblock.io import open_model
    from geoblock.simulate.onboard import measure_attitude_record

    out = []
    for rel in (*DG, *SPOT, *SPOT6, *PLEIADES):
        path = root / rel
        if not path.is_file():
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model: Any = open_model(path)
        ifov, period = _ifov(model), float(model.line_times.line_period_s)
        if rel in PLEIADES:
            t, q = _pleiades_quaternions(path)
            span = (float(t[0]), float(t[-1]))
        else:
            t, q = model.attitude.time_s, model.attitude.quaternion
            span = _image_span(model)
        rec = measure_attitude_record(t, q, span, ifov, model.shape[1], period)
        out.append(Measured(rel, SENSOR[rel], FAMILY[rel], rec, ifov, period))
    return out


def family_constants(measured: list[Measured]) -> dict[str, dict[str, Any]]:
    """Quadratic-mean RMS per axis and median slope per family (what the constants store)."""
    fams: dict[str, list[Measured]] = {}
    for m in measured:
        fams.setdefault(m.family, []).append(m)
    out = {}
    for fam, ms in fams.items():
        rms = np.sqrt(np.mean([m.record.rms_rad**2 for m in ms], axis=0))
        out[fam] = {"rms_rad": rms, "slope": float(np.median([m.record.slope for m in ms])),
                    "nyquist_hz": min(0.5 * m.record.rate_hz for m in ms), "records": len(ms)}
    return out


def spot5_look(root: Path) -> dict[str, float]:
    """SPOT5.DIM's look-angle table departure from a cubic, px (and a quintic)."""
    from geoblock.io import open_model
    from geoblock.simulate.onboard import look_departure

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model: Any = open_model(root / SPOT[4])
    v = model.look.vectors
    tan = np.stack([v[:, 0] / v[:, 2], v[:, 1] / v[:, 2]], axis=-1)
    ifov = _ifov(model)
    dep3 = look_departure(tan, 3) / ifov
    dep5 = look_departure(tan, 5) / ifov
    return {"ifov_rad": ifov, "along_rms": float(np.sqrt(np.mean(dep3[:, 0] ** 2))),
            "across_rms": float(np.sqrt(np.mean(dep3[:, 1] ** 2))),
            "along_max": float(np.abs(dep3[:, 0]).max()),
            "across_max": float(np.abs(dep3[:, 1]).max()),
            "quintic_max": float(np.abs(dep5).max())}


def dg_ephemeris_sigma(root: Path) -> float:
    """sqrt of the mean diagonal of the DG EPH position covariances, metres."""
    from geoblock_quickbird.isd import read_isd  # type: ignore[import-untyped]

    diag = []
    for rel in DG:
        path = root / rel
        if path.is_file():
            cov = read_isd(path).position_covariance_m2  # (n, 6): xx xy xz yy yz zz
            diag.append(cov[:, [0, 3, 5]])
    return float(math.sqrt(np.mean(np.concatenate(diag))))


def preset_timings() -> list[tuple[str, str, float]]:
    from geoblock.simulate import sensors as S

    rows = []
    for spec in (*S.SPOT5_STRIPS, S.QUICKBIRD, S.SPOT1A, *S.SPOT5_STRIPS_SMALL,
                 S.QUICKBIRD_SMALL, S.SPOT1A_SMALL):
        for mode in ("bias-drift", "realistic"):
            t = time.perf_counter()
            S.simulate_sensor(spec.replace(onboard_errors=mode))
            rows.append((spec.name, mode, time.perf_counter() - t))
    return rows


def main(argv: list[str]) -> int:
    root = data_dir(argv[1] if len(argv) > 1 else None)
    if not root.is_dir():
        print(f"no data directory {root}")
        return 1
    measured = measure_all(root)
    print("| record | sensor | rate Hz (Nyquist) | span s | samples | RMS roll/pitch/yaw urad "
          "| RMS roll/pitch/yaw px | dominant Hz roll/pitch/yaw | slope | spline 0.01 px: "
          "lines (s, residual px) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for m in measured:
        r = m.record
        urad = "/".join(f"{x * 1e6:.3f}" for x in r.rms_rad)
        px = "/".join(f"{x:.3f}" for x in r.rms_px)
        dom = "/".join(f"{x:.2f}" for x in r.dominant_hz)
        if math.isnan(r.spline_lines):
            spline = f"< 2 samples ({r.spline_residual_px:.4f} px at 2 samples)"
        else:
            spline = (f"{r.spline_lines:.0f} ({r.spline_lines * abs(m.line_period_s):.3f} s, "
                      f"{r.spline_residual_px:.4f})")
        print(f"| {Path(m.file).name} | {m.sensor} | {r.rate_hz:.2f} ({0.5 * r.rate_hz:.2f}) | "
              f"{r.span_s:.2f} | {r.samples} | {urad} | {px} | {dom} | {r.slope:.2f} | "
              f"{spline} |")
    print("\nFamilies (quadratic mean of the RMS, median slope):")
    for fam, c in family_constants(measured).items():
        print(f"  {fam}: {c['records']} records, RMS roll/pitch/yaw "
              f"{', '.join(f'{x:.3g}' for x in c['rms_rad'])} rad, slope {c['slope']:.3g}, "
              f"Nyquist {c['nyquist_hz']:.3g} Hz")
    look = spot5_look(root)
    print(f"\nSPOT5.DIM look angles minus a cubic: along {look['along_rms']:.4f} px RMS "
          f"({look['along_max']:.4f} max), across {look['across_rms']:.4f} px RMS "
          f"({look['across_max']:.4f} max), IFOV {look['ifov_rad']:.4g} rad; minus a quintic: "
          f"{look['quintic_max']:.2g} px max")
    try:
        print(f"DG EPH position sigma (sqrt mean diagonal): {dg_ephemeris_sigma(root):.4f} m")
    except ImportError:
        print("DG EPH covariance: geoblock-quickbird not installed")
    print("\nBuilding the sensor presets (simulate_sensor), seconds:")
    for name, mode, sec in preset_timings():
        print(f"  {name:22s} {mode:10s} {sec:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
