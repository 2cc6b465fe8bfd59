"""A small simulated block with known truth for ``geoblock match``: three 300 x 300 px
SPOT-5-like images (2.5 m GSD) of one ridged, textured scene, seen at incidences of +12, -12
and 0 degrees (the first two: a stereo pair with a base-to-height ratio of about 0.4), with
on-board models off by 20-30 m and a measured DEM (10 m posts, RMSEz 5 m) besides the true
terrain the images were rendered on."""

from __future__ import annotations

import numpy as np
import pytest

import geoblock
from geoblock.simulate.scenario import scenario_from_dict
from geoblock.workflows import run_scenario

IMAGES = ("a", "b", "c")


def scenario() -> dict:
    image = {"preset": "spot5-strip1", "centre_lon": 120.95, "shape": [300, 300], "gsd_m": 2.5}
    return {
        "name": "match-triplet", "description": "three views of one scene, for geoblock match",
        "seed": 17, "method": "dg",
        "images": [{"id": "a", **image, "incidence_deg": 12.0},
                   {"id": "b", **image, "incidence_deg": -12.0,
                    "epoch": "2003-06-23T02:40:00Z"},
                   {"id": "c", **image, "incidence_deg": 0.5, "onboard_rmse_m": 20.0,
                    "epoch": "2003-06-25T02:40:00Z"}],
        "terrain": {"kind": "ridged", "relief": [100.0, 400.0], "resolution_m": 10.0,
                    "vertical": "ellipsoid", "margin_m": 300.0},
        "dems": [{"name": "dem", "spacing_m": 20.0, "rmse_z": 5.0}],
        "points": {"gcp": 4, "icp": 0, "tp": [0, 0], "ictp": [0, 0], "sigma_px": 0.3},
        # fields of about 30 px: SIFT finds their corners (the default's 60 px fields give a
        # third as many keypoints on a 300 px image)
        "render": {"enabled": True, "dtype": "uint8", "noise_dn": 1.0,
                   "texture_scale_px": 0.5},
        "report": {"distance_plot": False, "gcp_study": False},
    }


class Truth:
    """Where a pixel of one image truly is in another: the TRUE model of the first on the TRUE
    terrain, projected by the TRUE model of the second."""

    def __init__(self, outdir):
        self.models = {i: geoblock.open_model(outdir / "images" / f"{i}_true.json")
                       for i in IMAGES}
        self.terrain = geoblock.open_dem(outdir / "terrain" / "truth.tif")

    def transfer(self, image_a, image_b, row, col):
        ground, status = geoblock.localize(self.models[image_a], row, col, self.terrain,
                                           warn=False)
        assert (status == 0).all()
        return self.models[image_b].project(ground.lon, ground.lat, ground.h)

    def errors(self, tie_points, image_a, image_b):
        """Distance (pixels of B) between each point's measurement in B and the truth of its
        measurement in A, for the points measured in both."""
        cols = tie_points if isinstance(tie_points, dict) else tie_points.to_columns()
        a = cols["image"] == image_a
        b = cols["image"] == image_b
        common = np.intersect1d(cols["id"][a], cols["id"][b])
        ia = a & np.isin(cols["id"], common)
        ib = b & np.isin(cols["id"], common)
        oa, ob = np.argsort(cols["id"][ia]), np.argsort(cols["id"][ib])
        r, c = self.transfer(image_a, image_b, cols["row"][ia][oa], cols["col"][ia][oa])
        return np.hypot(cols["row"][ib][ob] - r, cols["col"][ib][ob] - c)


@pytest.fixture(scope="session")
def triplet(tmp_path_factory):
    """The simulated block: its directory (block.toml, images/, terrain/) and its truth."""
    out = tmp_path_factory.mktemp("match-triplet")
    run_scenario(scenario_from_dict(scenario()), out)
    return out, Truth(out)
