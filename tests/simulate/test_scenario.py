"""Scenarios: presets, the TOML form and its errors, reading and writing scenario files."""

from __future__ import annotations

import tomllib

import pytest

from geoblock.errors import MetadataFieldError, ScenarioError
from geoblock.io.blocks import dumps_toml
from geoblock.simulate.presets import DEMO_SIZES, demo_dict
from geoblock.simulate.scenario import (
    PRESETS,
    Scenario,
    demo_scenario,
    derived_seed,
    load_scenario,
    preset,
    preset_dict,
    read_scenario,
    scenario_from_dict,
    scenario_to_dict,
    write_scenario,
)
from geoblock.simulate.sensors import SPOT5_STRIPS


# ---------------------------------------------------------------------------- presets
@pytest.mark.parametrize("name", list(PRESETS))
@pytest.mark.parametrize("variant", ["small", "full"])
def test_presets_parse(name, variant):
    sc = preset(name, variant)
    assert sc.source == f"preset:{name}/{variant}"
    assert sc.dems and sc.images
    # the small variant keeps the footprint: same GSD x columns as the full one
    full = preset(name, "full")
    for a, b in zip(sc.images, full.images, strict=True):
        assert a.spec.gsd_m * a.spec.shape[1] == pytest.approx(b.spec.gsd_m * b.spec.shape[1],
                                                                rel=0.01)


def test_preset_values_follow_the_papers():
    teo = preset("teo2010-spot5", "full")
    assert [im.spec.incidence_deg for im in teo.images] == [5.2, 5.7, -14.8]
    assert [im.spec.shape for im in teo.images] == [(24000, 24000)] * 3
    assert teo.terrain.relief == (0.0, 3800.0) and teo.terrain.kind == "ridged"
    assert [(d.spacing_m) for d in teo.dems] == [40.0]
    assert teo.points.gcp == 9 and teo.points.tp == (13, 32) and teo.points.ictp[0] > 0
    qb = preset("aguilar2007-quickbird", "full")
    assert qb.images[0].spec.gsd_m == 0.62 and qb.images[0].spec.roll_deg == 8.0
    assert qb.terrain.relief == (50.0, 850.0)
    assert [(d.spacing_m, d.rmse_z) for d in qb.dems] == [(2.0, 0.31), (5.0, 1.75), (20.0, 5.82)]
    assert (qb.points.gcp, qb.points.icp, qb.points.design, qb.points.cells) == (
        45, 79, "stratified", 3)
    chen = preset("chen1993-spot1a", "full")
    assert chen.points.gcp == 21 and chen.points.icp > 0
    assert chen.terrain.relief[1] - chen.terrain.relief[0] == 950.0
    assert chen.images[0].spec.shape == (6000, 6000)


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ScenarioError, match="teo2010-spot5.*aguilar2007-quickbird.*chen1993"):
        load_scenario("nope")
    with pytest.raises(ScenarioError, match="variant"):
        preset("teo2010-spot5", "huge")


# ---------------------------------------------------------------------------- TOML
def test_toml_round_trip(tmp_path):
    sc = preset("teo2010-spot5", "small", seed=5)
    path = tmp_path / "s.toml"
    path.write_text(dumps_toml(scenario_to_dict(sc)))
    back = read_scenario(path)
    assert back.replace(source=sc.source) == sc
    assert [im.spec for im in back.images] == [im.spec for im in sc.images]
    other = sc.with_seed(6)
    assert other.seed == 6 and other.images[0].spec.seed != sc.images[0].spec.seed
    assert other.replace(seed=5, images=sc.images) == sc


def test_file_starting_from_a_preset(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('preset = "teo2010-spot5"\nseed = 3\n[points]\ngcp = 4\n'
                    '[terrain]\nrelief = [100.0, 2000.0]\n')
    sc = load_scenario(path, variant="full")
    assert sc.seed == 3 and sc.points.gcp == 4 and sc.points.icp == 20  # merged
    assert sc.terrain.relief == (100.0, 2000.0) and sc.terrain.kind == "ridged"
    assert sc.images[0].spec.shape == (24000, 24000)
    # a different seed re-seeds the sensors
    assert load_scenario(path, seed=4).images[0].spec.seed != sc.images[0].spec.seed


def test_image_overrides_and_custom_sensor():
    data = {
        "seed": 1,
        "images": [
            {"id": "a", "preset": "spot5-strip1", "scale": 40, "onboard_rmse_m": 5.0},
            {"id": "b", "name": "custom", "altitude_m": 700e3, "inclination_deg": 98.0,
             "ascending": True, "centre_lon": 10.0, "centre_lat": 45.0, "gsd_m": 20.0,
             "shape": [300, 400]},
        ],
        "dems": [{"name": "dem", "spacing_m": 30.0, "rmse_z": 2.0}],
    }
    sc = scenario_from_dict(data, "x.toml")
    a, b = sc.images
    assert a.spec.onboard_rmse_m == 5.0 and a.spec.gsd_m == SPOT5_STRIPS[0].gsd_m * 40
    assert a.spec.name == "a" and b.spec.name == "custom" and b.spec.shape == (300, 400)


@pytest.mark.parametrize("change, key, message", [
    ({"colour": 1}, "colour", "unknown key"),
    ({"seed": "one"}, "seed", "an integer"),
    ({"seed": -1}, "seed", ">= 0"),
    ({"images": []}, "images", "at least one"),
    ({"images": ["strip1"]}, r"images\[0\]", "must be a table, got a string"),
    ({"dems": [{"name": "d", "spacing_m": 1.0, "rmse_z": 1.0}, 5]}, r"dems\[1\]",
     "must be a table, got an integer"),
    ({"images": [{"id": "a", "preset": "quickbird", "ascending": 1}]},
     r"images\[0\]\.ascending", "true or false"),
    ({"images": [{"id": "a", "preset": "quickbird", "shape": [1.5, 2]}]},
     r"images\[0\]\.shape", r"\[rows, cols\] integers"),
    ({"points": "many"}, "points", "must be a table"),
    ({"images": [{"id": "a", "preset": "landsat"}]}, r"images\[0\]\.preset", "spot5-strip1"),
    ({"images": [{"id": "a", "preset": "quickbird", "focal": 1.0}]}, r"images\[0\]\.focal",
     "unknown key"),
    ({"images": [{"id": "a", "gsd_m": 2.0}]}, r"images\[0\]", "altitude_m"),
    ({"images": [{"id": "a", "preset": "quickbird", "gsd_m": -1.0}]}, r"images\[0\]", "gsd_m"),
    ({"images": [{"id": "a/b", "preset": "quickbird"}]}, r"images\[0\]\.id", "file-name"),
    ({"terrain": {"kind": "alpine"}}, "terrain.kind", "ridged, fractal"),
    ({"terrain": {"relief": [5.0, 1.0]}}, "terrain.relief", "high"),
    ({"terrain": {"crs": "EPSG:nope"}}, "terrain.crs", "not a CRS"),
    ({"dems": [{"name": "d", "spacing_m": 0.0, "rmse_z": 1.0}]}, r"dems\[0\]\.spacing_m", "> 0"),
    ({"points": {"gcp": 2.5}}, "points.gcp", "an integer"),
    ({"points": {"tp": [5, 2]}}, "points.tp", "high must be"),
    ({"points": {"design": "grid"}}, "points.design", "stratified, random"),
    ({"render": {"dtype": "float32"}}, "render.dtype", "uint8, uint16"),
    ({"variant": "small"}, "variant", "preset"),
])
def test_errors_name_the_file_and_the_key(change, key, message):
    data = preset_dict("chen1993-spot1a", "small")
    data.update(change)
    with pytest.raises(ScenarioError, match=rf"^my\.toml: {key}: .*{message}"):
        scenario_from_dict(data, "my.toml")


def test_file_errors(tmp_path):
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("seed = = 1\n")
    with pytest.raises(ScenarioError, match="bad.toml: not valid TOML.*line 1"):
        load_scenario(bad)
    plain = tmp_path / "plain.toml"
    plain.write_text(dumps_toml(preset_dict("chen1993-spot1a")))
    with pytest.raises(ScenarioError, match="--variant applies to presets"):
        load_scenario(plain, variant="full")


def test_scenario_errors_are_geoblock_value_errors():
    from geoblock.errors import GeoblockError

    with pytest.raises(ScenarioError) as info:
        scenario_from_dict({"seed": 1.5}, "x.toml")
    assert isinstance(info.value, GeoblockError) and isinstance(info.value, ValueError)
    assert not isinstance(info.value, MetadataFieldError)
    assert str(info.value).startswith("x.toml: seed: must be an integer")


def test_write_scenario_round_trips_through_io(tmp_path):
    sc = preset("aguilar2007-quickbird", "small", seed=4)
    path = write_scenario(tmp_path / "scenario.toml", sc)
    text = path.read_text()
    assert text.startswith("# geoblock scenario") and "preset:aguilar2007-quickbird" in text
    assert tomllib.loads(text)["seed"] == 4
    back = read_scenario(path)
    assert back.replace(source=sc.source) == sc
    assert Scenario.from_dict(sc.to_dict(), "again").replace(source=sc.source) == sc
    # a missing file is a ScenarioError naming it
    with pytest.raises(ScenarioError, match="missing.toml"):
        read_scenario(tmp_path / "missing.toml")


def test_demo_scenario_sizes():
    assert DEMO_SIZES == ("small", "tiny")
    small, tiny = demo_scenario("small"), demo_scenario("tiny", seed=3)
    assert small.source == "demo:small" and small.seed == 2010 and tiny.seed == 3
    assert small.images == preset("teo2010-spot5", "small").images
    assert [im.spec.shape for im in tiny.images] == [(200, 200)] * 3
    assert tiny.dems[0].name == "dem200" and tiny.name == "teo2010-spot5-tiny"
    assert demo_dict("tiny")["description"].endswith("; the geoblock demo")
    with pytest.raises(ScenarioError, match="small, tiny"):
        demo_scenario("huge")


def test_derived_seeds_are_stable():
    # the files of a scenario depend on these values: they must not change between versions
    assert derived_seed(2010, 2) == derived_seed(2010, 2)
    assert derived_seed(2010, 2) != derived_seed(2010, 3) != derived_seed(2011, 2)
    assert derived_seed(2010, 1, 0) != derived_seed(2010, 1, 1)
    assert preset("teo2010-spot5").images[0].spec.seed == derived_seed(2010, 1, 0)
