"""Named scenario presets: the papers' set-ups as the TOML form of a scenario.

A preset is a plain dictionary in the form of a scenario file (``preset_dict(name,
variant)``); :func:`geoblock.simulate.scenario.preset` parses it into a
:class:`~geoblock.simulate.scenario.Scenario`. Change the dictionary and pass it to
:func:`~geoblock.simulate.scenario.scenario_from_dict` for a variation of a preset.

``teo2010-spot5``
    Teo et al. (2010): three SPOT-5 strips (2.5 m GSD, incidence 5.2, 5.7 and -14.8 deg,
    10-15 % overlaps) over 0-3800 m ridged terrain, a 40 m DEM, 9 GCPs per strip, 13-32 TPs
    per overlap, ICPs and ICTPs.
``aguilar2007-quickbird``
    Aguilar et al. (2007): one QuickBird basic scene (0.62 m GSD, 8 deg off nadir) over
    50-850 m rolling terrain, 45 GCPs stratified over a 3 x 3 grid, 79 ICPs, DEMs of 2 / 5 /
    20 m spacing with RMSEz 0.31 / 1.75 / 5.82 m.
``chen1993-spot1a``
    Chen & Lee (1993): one SPOT 1A scene (10 m, 6000 x 6000 px) over 950 m of relief, 21 GCPs
    and check points, a 40 m DTM.
``continental-spot-100``
    A block of 10 strips x 10 scenes of a SPOT-like 20 m sensor (60 x 60 km scenes, 25 % side
    and 10 % along-track overlap) over 600 x 600 km of France, laid out as the large
    points-only blocks of :mod:`geoblock.simulate.large` (``continental-spot-1000``,
    ``continental-spot-10000``: :data:`~geoblock.simulate.large.LARGE_PRESETS`): rendered
    (small: 400 x 400 px scenes at 150 m, a few minutes on two cores) for matching, 30-60 TPs
    per overlapping pair, a GCP and two ICPs per image, a 1 km DEM.

The images' on-board errors are ``realistic`` (biases and drifts plus the attitude wander,
look-angle and orbital-period ephemeris errors measured on real products: the sensor presets'
mix, :mod:`geoblock.simulate.onboard`) unless the scenario says ``onboard_errors =
"bias-drift"``.

Each comes in a ``small`` variant (images 10-40 times smaller with the same footprint, a
coarser true terrain: seconds) and a ``full`` variant (the papers' image sizes).
:func:`demo_dict` is the scenario of ``geoblock demo`` (the small Teo et al. block, or a
``tiny`` one for tests).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from geoblock.errors import ScenarioError
from geoblock.simulate import sensors as _sensors
from geoblock.simulate.sensors import OrbitSensorSpec

__all__ = [
    "DEMO_SIZES",
    "PRESETS",
    "SENSOR_PRESETS",
    "VARIANTS",
    "demo_dict",
    "preset_dict",
]

VARIANTS = ("small", "full")
"""Variants of the named presets."""

#: Sensor presets an image can start from (``preset = "spot5-strip1"``), by name.
SENSOR_PRESETS: dict[str, OrbitSensorSpec] = {
    "spot5-strip1": _sensors.SPOT5_STRIPS[0],
    "spot5-strip2": _sensors.SPOT5_STRIPS[1],
    "spot5-strip3": _sensors.SPOT5_STRIPS[2],
    "quickbird": _sensors.QUICKBIRD,
    "spot1a": _sensors.SPOT1A,
    "spot-hrg20": _sensors.SPOT_HRG20,
}

#: Sizes of the demo's scenario: ``small`` (the teo2010-spot5 small preset) and ``tiny``
#: (200 x 200 px strips at 300 m, a 200 m DEM: a few seconds, for tests).
DEMO_SIZES = ("small", "tiny")


def _teo(variant: str) -> dict[str, Any]:
    small = variant == "small"
    return {
        "name": f"teo2010-spot5-{variant}",
        "description": (
            "Teo et al. (2010): three SPOT-5 supermode strips over Taiwan (2.5 m GSD, "
            "incidence 5.2, 5.7 and -14.8 deg, 10-15 % overlaps), 0-3800 m ridged terrain, "
            "a 40 m DEM, 9 GCPs per strip, 13-32 TPs per overlap, ICPs and ICTPs"
            + (" (small: 600 x 600 px strips at 100 m, same footprints)" if small else "")
        ),
        "seed": 2010,
        "method": "dg",
        "images": [{"id": f"strip{k}", "preset": f"spot5-strip{k}",
                    **({"scale": 40} if small else {})} for k in (1, 2, 3)],
        "terrain": {"kind": "ridged", "relief": [0.0, 3800.0],
                    "resolution_m": 100.0 if small else 40.0,
                    **({} if small else {"max_slope_deg": 70.0}),
                    "vertical": "ellipsoid", "margin_m": 3000.0},
        # Teo et al. give no RMSEz for their 40 m DEM: 5 m is assumed
        "dems": [{"name": "dem40", "spacing_m": 40.0, "rmse_z": 5.0}],
        "points": {"gcp": 9, "icp": 20, "design": "stratified", "cells": 3, "tp": [13, 32],
                   "ictp": [5, 10], "sigma_px": 0.5 / 40 if small else 0.5,
                   "sigma_e": 3.0, "sigma_n": 3.0, "sigma_h": 3.0},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": False, "gcp_study": False},
    }


def _aguilar(variant: str) -> dict[str, Any]:
    small = variant == "small"
    dems = ([{"name": "dem5", "spacing_m": 5.0, "rmse_z": 1.75},
             {"name": "dem20", "spacing_m": 20.0, "rmse_z": 5.82}] if small else
            [{"name": "dem2", "spacing_m": 2.0, "rmse_z": 0.31},
             {"name": "dem5", "spacing_m": 5.0, "rmse_z": 1.75},
             {"name": "dem20", "spacing_m": 20.0, "rmse_z": 5.82}])
    return {
        "name": f"aguilar2007-quickbird-{variant}",
        "description": (
            "Aguilar et al. (2007): a QuickBird basic scene over Almeria (0.62 m GSD, 8 deg "
            "off nadir), 50-850 m rolling terrain, 45 GCPs stratified over a 3 x 3 grid, "
            "79 ICPs, DEMs of 2 / 5 / 20 m spacing with RMSEz 0.31 / 1.75 / 5.82 m"
            + (" (small: ~690 x 690 px at 24.8 m, same footprint; the 5 and 20 m DEMs)"
               if small else "")
        ),
        "seed": 2007,
        "method": "rpcv1",
        "images": [{"id": "quickbird", "preset": "quickbird", **({"scale": 40} if small else {})}],
        "terrain": {"kind": "fractal", "relief": [50.0, 850.0], "hurst": 0.8,
                    "resolution_m": 20.0 if small else 4.0, "vertical": "ellipsoid",
                    "margin_m": 500.0},
        "dems": dems,
        "points": {"gcp": 45, "icp": 79, "design": "stratified", "cells": 3, "tp": 0, "ictp": 0,
                   "sigma_px": 0.5 / 40 if small else 0.5, "sigma_e": 0.05, "sigma_n": 0.05,
                   "sigma_h": 0.1},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": True, "gcp_study": True},
    }


def _chen(variant: str) -> dict[str, Any]:
    small = variant == "small"
    return {
        "name": f"chen1993-spot1a-{variant}",
        "description": (
            "Chen & Lee (1993): a SPOT 1A scene (10 m, 6000 x 6000 px, 1.5 ms line period) "
            "over 950 m of relief, 21 GCPs, check points, a 40 m DTM"
            + (" (small: 600 x 600 px at 100 m, same footprint)" if small else "")
        ),
        "seed": 1993,
        "method": "dg",
        "images": [{"id": "spot1a", "preset": "spot1a", **({"scale": 10} if small else {})}],
        "terrain": {"kind": "ridged", "relief": [150.0, 1100.0],
                    "resolution_m": 100.0 if small else 20.0, "vertical": "ellipsoid",
                    "margin_m": 3000.0},
        "dems": [{"name": "dem40", "spacing_m": 40.0, "rmse_z": 5.0}],
        "points": {"gcp": 21, "icp": 20, "design": "stratified", "cells": 3, "tp": 0,
                   "ictp": 0, "sigma_px": 0.3 / 10 if small else 0.3, "sigma_e": 1.0,
                   "sigma_n": 1.0, "sigma_h": 1.0},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": False, "gcp_study": False},
    }


def _continental(variant: str) -> dict[str, Any]:
    from geoblock.simulate.large import LargeBlockSpec, layout

    small = variant == "small"
    scale = 7.5 if small else 1.0  # 400 x 400 px at 150 m, or 3000 x 3000 at 20 m
    spec = LargeBlockSpec(name="continental-spot-100", strips=10, scenes=10, tps=0, seed=100)
    lay = layout(spec)
    images = []
    for i, image_id in enumerate(lay.ids.tolist()):
        images.append({"id": image_id, "preset": "spot-hrg20",
                       **({"scale": scale} if small else {}),
                       "centre_lon": round(float(lay.lon[i]), 7),
                       "centre_lat": round(float(lay.lat[i]), 7),
                       "incidence_deg": round(float(lay.incidence_deg[i]), 4),
                       "epoch": lay.epoch[i]})
    return {
        "name": f"continental-spot-100-{variant}",
        "description": (
            "10 strips x 10 scenes of a SPOT-like 20 m sensor (60 x 60 km scenes, 25 % side "
            "and 10 % along-track overlap, incidence within +-5 deg) over 600 x 600 km of "
            "France, 0-2500 m fractal terrain, a 1 km DEM, a GCP and two ICPs per image, "
            "30-60 TPs and 3-6 ICTPs per overlapping pair"
            + (" (small: 400 x 400 px scenes at 150 m)" if small else "")
        ),
        "seed": 100,
        "method": "dg",
        "images": images,
        "terrain": {"kind": "fractal", "relief": [0.0, 2500.0], "hurst": 0.8,
                    "resolution_m": 250.0 if small else 100.0, "vertical": "ellipsoid",
                    "margin_m": 5000.0},
        "dems": [{"name": "dem1000", "spacing_m": 1000.0, "rmse_z": 10.0}],
        "points": {"gcp": 1, "icp": 2, "design": "random", "cells": 1, "tp": [30, 60],
                   "ictp": [3, 6], "sigma_px": 0.3 / scale, "sigma_e": 1.0,
                   "sigma_n": 1.0, "sigma_h": 1.0},
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 1.0},
        "report": {"distance_plot": False, "gcp_study": False},
    }


#: Named scenario presets: name -> one-line description.
PRESETS: dict[str, str] = {
    "teo2010-spot5": "Teo et al. 2010: three SPOT-5 strips, 0-3800 m, 40 m DEM, GCP/ICP/TP/ICTP",
    "aguilar2007-quickbird": "Aguilar et al. 2007: QuickBird basic, 45 GCPs 3x3, 79 ICPs, "
                             "2/5/20 m DEMs",
    "chen1993-spot1a": "Chen & Lee 1993: SPOT 1A, 21 GCPs, check points, 950 m relief",
    "continental-spot-100": "10 x 10 SPOT-like 20 m scenes over 600 x 600 km, 30-60 TPs per "
                            "overlap, rendered for matching",
}
_PRESET_BUILDERS: dict[str, Callable[[str], dict[str, Any]]] = {
    "teo2010-spot5": _teo, "aguilar2007-quickbird": _aguilar, "chen1993-spot1a": _chen,
    "continental-spot-100": _continental,
}


def preset_dict(name: str, variant: str = "small") -> dict[str, Any]:
    """The TOML form of a named preset (a fresh dictionary: change it and pass it to
    :func:`~geoblock.simulate.scenario.scenario_from_dict`).

    Raises
    ------
    ScenarioError
        Unknown preset (the message lists the known ones) or variant.
    """
    if name not in _PRESET_BUILDERS:
        raise ScenarioError(f"unknown scenario preset {name!r}; known: {', '.join(PRESETS)}")
    if variant not in VARIANTS:
        raise ScenarioError(f"unknown variant {variant!r} of {name}; known: "
                            f"{', '.join(VARIANTS)}")
    return _PRESET_BUILDERS[name](variant)


def demo_dict(size: str = "small") -> dict[str, Any]:
    """The TOML form of the demo's scenario (a fresh dictionary).

    ``small`` is the ``teo2010-spot5`` small preset; ``tiny`` shrinks its strips to 200 x 200
    px at 300 m, its true terrain to 300 m posts and its DEM to 200 m, with fewer points.

    Raises
    ------
    ScenarioError
        Unknown size (the message lists :data:`DEMO_SIZES`).
    """
    if size not in DEMO_SIZES:
        raise ScenarioError(f"demo: unknown size {size!r}; known: {', '.join(DEMO_SIZES)}")
    data = preset_dict("teo2010-spot5", "small")
    if size == "tiny":
        for image in data["images"]:
            image["scale"] = 120
        data["terrain"]["resolution_m"] = 300.0
        data["dems"] = [{"name": "dem200", "spacing_m": 200.0, "rmse_z": 10.0}]
        data["points"].update(icp=9, tp=[8, 12], ictp=[4, 6])
        data["name"] = "teo2010-spot5-tiny"
    data["description"] += "; the geoblock demo"
    return data
