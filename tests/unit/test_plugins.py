"""Plugin loading through real entry points: fake distributions installed on sys.path."""

from __future__ import annotations

import sys
import textwrap
import warnings

import pytest

import geoblock
import geoblock.testing
from geoblock.errors import DuplicateModelError, PluginError, PluginWarning, UnknownModelError
from geoblock.models.registry import build_registry
from geoblock.plugins import (
    PLUGIN_MODULES_VARIABLE,
    create_plugin_manager,
    disable_plugin_module,
    enable_plugin_module,
    list_plugins,
    plugin_modules,
    refresh_plugins,
)
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom

SYNTHETIC = {"synthetic-affine", "synthetic-pushbroom"}

MODEL_PLUGIN = '''
from geoblock import hookimpl
from geoblock.testing.synthetic import AffineCamera


class {cls}(AffineCamera):
    name = "{model}"


@hookimpl
def geoblock_register_sensor_models(register):
    register({cls})
'''


def install_distribution(root, dist, entry_points, modules):
    """Write a minimal installed distribution (dist-info + modules) under ``root``."""
    info = root / f"{dist.replace('-', '_')}-1.2.3.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 1.2.3\n")
    eps = "\n".join(f"{name} = {target}" for name, target in entry_points.items())
    (info / "entry_points.txt").write_text(f"[geoblock]\n{eps}\n")
    for module, source in modules.items():
        (root / f"{module}.py").write_text(textwrap.dedent(source))


@pytest.fixture
def site(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv("GEOBLOCK_PLUGINS", raising=False)
    yield tmp_path
    for name in [m for m in sys.modules if m.startswith("gb_")]:
        del sys.modules[name]  # each test installs its own gb_* modules


def test_entry_point_plugin_registers_a_model(site):
    install_distribution(
        site, "geoblock-good", {"good": "gb_good"},
        {"gb_good": MODEL_PLUGIN.format(cls="Good", model="good-camera")},
    )
    pm = create_plugin_manager()
    registry = build_registry(pm)
    assert "good-camera" in registry
    assert registry.owner("good-camera") == "good"
    info = {p.name: p for p in list_plugins(pm)}["good"]
    assert (info.distribution, info.version) == ("geoblock-good", "1.2.3")
    assert info.models == ("good-camera",)
    assert "geoblock_register_sensor_models" in info.hooks


def test_plugin_that_raises_on_import_is_skipped_with_a_warning(site):
    install_distribution(
        site, "geoblock-broken", {"broken": "gb_broken"},
        {"gb_broken": "raise ImportError('needs libfoo, which is missing')\n"},
    )
    install_distribution(
        site, "geoblock-good", {"good": "gb_good"},
        {"gb_good": MODEL_PLUGIN.format(cls="Good", model="good-camera")},
    )
    with pytest.warns(PluginWarning, match=r"'broken'.*geoblock-broken.*needs libfoo"):
        pm = create_plugin_manager()
    registry = build_registry(pm)
    assert "good-camera" in registry and "image-correction" in registry
    assert "broken" not in [p.name for p in list_plugins(pm)]


def test_two_plugins_registering_one_name_is_an_error_naming_both(site):
    install_distribution(
        site, "geoblock-one", {"one": "gb_one"},
        {"gb_one": MODEL_PLUGIN.format(cls="One", model="same-name")},
    )
    install_distribution(
        site, "geoblock-two", {"two": "gb_two"},
        {"gb_two": MODEL_PLUGIN.format(cls="Two", model="same-name")},
    )
    pm = create_plugin_manager()
    with pytest.raises(
        DuplicateModelError, match=r"'same-name'.*'one'.*gb_one\.One.*'two'.*gb_two\.Two"
    ) as err:
        build_registry(pm)
    assert isinstance(err.value, geoblock.GeoblockError)


def test_plugin_cannot_take_a_builtin_name(site):
    install_distribution(
        site, "geoblock-clash", {"clash": "gb_clash"},
        {"gb_clash": MODEL_PLUGIN.format(cls="Clash", model="image-correction")},
    )
    with pytest.raises(DuplicateModelError, match="geoblock._default_plugin"):
        build_registry(create_plugin_manager())


def test_plugin_whose_register_hook_raises_is_skipped(site):
    install_distribution(
        site, "geoblock-bad", {"bad": "gb_bad"},
        {"gb_bad": """
            from geoblock import hookimpl

            @hookimpl
            def geoblock_register_sensor_models(register):
                raise RuntimeError("boom")
        """},
    )
    pm = create_plugin_manager()
    with pytest.warns(PluginWarning, match=r"'bad' failed to register.*boom"):
        registry = build_registry(pm)
    assert "image-correction" in registry


def test_invalid_model_class_is_skipped_with_a_warning(site):
    install_distribution(
        site, "geoblock-invalid", {"invalid": "gb_invalid"},
        {"gb_invalid": """
            from geoblock import hookimpl

            class NotAModel:
                name = "Bad Name"

            @hookimpl
            def geoblock_register_sensor_models(register):
                register(NotAModel)
        """},
    )
    with pytest.warns(PluginWarning, match=r"'invalid'.*lowercase-kebab"):
        build_registry(create_plugin_manager())


def test_misspelt_hook_is_reported(site):
    install_distribution(
        site, "geoblock-typo", {"typo": "gb_typo"},
        {"gb_typo": """
            from geoblock import hookimpl

            @hookimpl
            def geoblock_register_sensor_modles(register):
                pass
        """},
    )
    with pytest.warns(PluginWarning, match=r"'typo'.*geoblock_register_sensor_modles"):
        pm = create_plugin_manager()
    assert pm.get_plugin("typo") is None


def test_geoblock_plugins_restricts_loading(site, monkeypatch):
    install_distribution(
        site, "geoblock-one", {"one": "gb_one"},
        {"gb_one": MODEL_PLUGIN.format(cls="One", model="one-camera")},
    )
    install_distribution(
        site, "geoblock-broken", {"broken": "gb_broken"}, {"gb_broken": "raise ImportError\n"},
    )
    monkeypatch.setenv("GEOBLOCK_PLUGINS", "one")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the broken plugin is not even imported
        registry = build_registry(create_plugin_manager())
    assert "one-camera" in registry and "image-correction" in registry
    monkeypatch.setenv("GEOBLOCK_PLUGINS", "")
    registry = build_registry(create_plugin_manager())
    assert "one-camera" not in registry and "image-correction" in registry


def test_trace_plugins(site, monkeypatch, capsys):
    monkeypatch.setenv("GEOBLOCK_TRACE_PLUGINS", "1")
    pm = create_plugin_manager(entry_points=False)
    (site / "x.json").write_text("{}")
    pm.hook.geoblock_read_sensor_model(path=site / "x.json", model_name=None, options={})
    assert "geoblock_read_sensor_model" in capsys.readouterr().err


def test_loading_is_lazy():
    import subprocess
    import sys

    code = (
        "import sys, geoblock, geoblock.plugins as p;"
        "print(p.get_plugin_manager.cache_info().currsize)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "0"


def test_global_registry_and_refresh():
    from geoblock.models import get_registry
    from geoblock.plugins import refresh_plugins

    first = get_registry()
    assert first is get_registry()
    refresh_plugins()
    assert get_registry() is not first
    # the synthetic test models: enabled for geoblock's tests (tests/conftest.py) and kept
    # across refresh_plugins()
    assert {"image-correction", *SYNTHETIC} <= set(get_registry())
    assert get_registry().owner("synthetic-affine") == "geoblock.testing.plugin"


# ---------------------------------------------------------------- the opt-in test models
@pytest.fixture
def without_synthetic_models(monkeypatch):
    """The process as a user has it: the synthetic test models not enabled."""
    monkeypatch.delenv(PLUGIN_MODULES_VARIABLE, raising=False)
    geoblock.testing.disable_synthetic_models()
    yield
    geoblock.testing.enable_synthetic_models()


def test_a_users_registry_has_no_test_models(without_synthetic_models):
    from geoblock.models import get_registry

    assert plugin_modules() == ()
    registry = get_registry()
    assert not SYNTHETIC & set(registry)
    assert {"image-correction", "linescan", "crop", "collocation"} <= set(registry)
    assert "geoblock.testing.plugin" not in [p.name for p in list_plugins()]
    assert not SYNTHETIC & set(build_registry(create_plugin_manager(modules=())))


def test_enable_synthetic_models_registers_them_and_survives_refresh(without_synthetic_models):
    from geoblock.models import get_registry

    assert "synthetic-affine" not in get_registry()
    geoblock.testing.enable_synthetic_models()
    geoblock.testing.enable_synthetic_models()  # twice: nothing more
    assert plugin_modules() == ("geoblock.testing.plugin",)
    assert SYNTHETIC <= set(get_registry())
    refresh_plugins()
    assert SYNTHETIC <= set(get_registry())
    info = {p.name: p for p in list_plugins()}["geoblock.testing.plugin"]
    assert (info.distribution, info.models) == ("geoblock", tuple(sorted(SYNTHETIC)))
    geoblock.testing.disable_synthetic_models()
    assert not SYNTHETIC & set(get_registry())


def test_synthetic_models_work_without_the_registry(without_synthetic_models, tmp_path):
    """Building, pickling and to_dict/from_dict of the classes need no registration; opening
    their JSON does, and the error says how to load them."""
    import pickle

    for model in (AffineCamera.example(), ConstantVelocityPushbroom.example(roll=0.01)):
        assert pickle.loads(pickle.dumps(model)) == model
        assert type(model).from_dict(model.to_dict()) == model
        path = geoblock.write_model(model, tmp_path / f"{model.name}.json")
        with pytest.raises(UnknownModelError) as info:
            geoblock.open_model(path)
        message = str(info.value)
        assert str(path) in message and repr(model.name) in message
        assert "GEOBLOCK_PLUGIN_MODULES=geoblock.testing.plugin" in message
        assert "enable_synthetic_models()" in message
    geoblock.testing.enable_synthetic_models()
    assert geoblock.open_model(path) == model


def test_wrapped_synthetic_model_json_names_the_test_model(without_synthetic_models, tmp_path):
    from geoblock.models.corrections import ImageCorrection

    path = geoblock.write_model(ImageCorrection(AffineCamera.example(), order=1),
                                tmp_path / "wrapped.json")
    with pytest.raises(UnknownModelError, match=r"'synthetic-affine' is one of geoblock's "
                       r"synthetic test models.*GEOBLOCK_PLUGIN_MODULES=geoblock\.testing\.plugin"):
        geoblock.open_model(path)


def test_unknown_model_json_gets_no_test_model_hint(tmp_path):
    path = tmp_path / "other.json"
    path.write_text('{"model": "someone-elses", "schema_version": 1}')
    with pytest.raises(UnknownModelError, match="someone-elses") as info:
        geoblock.open_model(path)
    assert "geoblock.testing.plugin" not in str(info.value)


# ---------------------------------------------------------------- GEOBLOCK_PLUGIN_MODULES
def test_plugin_modules_variable_loads_modules_without_entry_points(site, monkeypatch):
    (site / "gb_dev.py").write_text(MODEL_PLUGIN.format(cls="Dev", model="dev-camera"))
    monkeypatch.setenv(PLUGIN_MODULES_VARIABLE, " gb_dev , geoblock.testing.plugin,gb_dev,")
    monkeypatch.setenv("GEOBLOCK_PLUGINS", "")  # restricts entry points, not these modules
    assert plugin_modules()[:2] == ("gb_dev", "geoblock.testing.plugin")
    pm = create_plugin_manager()
    registry = build_registry(pm)
    assert registry.owner("dev-camera") == "gb_dev"
    assert registry.owner("synthetic-affine") == "geoblock.testing.plugin"
    info = {p.name: p for p in list_plugins(pm)}["gb_dev"]
    assert (info.distribution, info.version, info.models) == (None, None, ("dev-camera",))
    # loaded whatever entry_points says; modules=() loads none
    assert "dev-camera" in build_registry(create_plugin_manager(entry_points=False))
    assert "dev-camera" not in build_registry(create_plugin_manager(modules=()))


def test_plugin_module_that_fails_to_import_is_skipped_with_a_warning(site, monkeypatch):
    (site / "gb_dev_broken.py").write_text("raise ImportError('needs libfoo')\n")
    monkeypatch.setenv(PLUGIN_MODULES_VARIABLE, "gb_dev_broken,gb_no_such_module")
    with pytest.warns(PluginWarning) as record:
        pm = create_plugin_manager()
    messages = [str(w.message) for w in record]
    assert any("'gb_dev_broken'" in m and "needs libfoo" in m for m in messages)
    assert any("'gb_no_such_module'" in m and "ModuleNotFoundError" in m for m in messages)
    assert "image-correction" in build_registry(pm)


def test_plugin_module_also_an_entry_point_loads_once(site, monkeypatch):
    install_distribution(
        site, "geoblock-good", {"good": "gb_good"},
        {"gb_good": MODEL_PLUGIN.format(cls="Good", model="good-camera")},
    )
    monkeypatch.setenv(PLUGIN_MODULES_VARIABLE, "gb_good,geoblock._default_plugin")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pm = create_plugin_manager()
    assert build_registry(pm).owner("good-camera") == "good"
    assert "gb_good" not in [p.name for p in list_plugins(pm)]


def test_enable_plugin_module_refuses_a_module_that_cannot_be_imported(site):
    (site / "gb_dev_broken.py").write_text("raise RuntimeError('boom')\n")
    with pytest.raises(PluginError, match=r"'gb_dev_broken'.*RuntimeError: boom"):
        enable_plugin_module("gb_dev_broken")
    assert "gb_dev_broken" not in plugin_modules()


def test_enable_and_disable_a_plugin_module(site):
    from geoblock.models import get_registry

    (site / "gb_dev.py").write_text(MODEL_PLUGIN.format(cls="Dev", model="dev-camera"))
    enable_plugin_module("gb_dev")
    try:
        assert "dev-camera" in get_registry()
        refresh_plugins()
        assert get_registry().owner("dev-camera") == "gb_dev"
    finally:
        disable_plugin_module("gb_dev")
    assert "dev-camera" not in get_registry()


# ============================================================================ aliases
def test_aliases_resolve_to_the_class_and_clash_like_names():
    from geoblock.models.registry import ModelRegistry
    from geoblock.testing.synthetic import AffineCamera

    class Aliased(AffineCamera):
        name = "aliased-camera"
        aliases = ("alias-one", "alias-two")

    class Clash(AffineCamera):
        name = "other-camera"
        aliases = ("alias-two",)

    registry = ModelRegistry()
    registry.register(Aliased, plugin="a")
    assert registry.get("alias-one") is registry.get("aliased-camera") is Aliased
    assert "alias-two" in registry and registry.names() == ["aliased-camera"]
    assert registry.aliases() == {"alias-one": "aliased-camera", "alias-two": "aliased-camera"}
    assert registry.owner("alias-one") == "a"
    data = Aliased.example().to_dict()
    data["model"] = "alias-one"
    assert registry.from_dict(data) == Aliased.example()
    with pytest.raises(DuplicateModelError, match="'alias-two'.*'a'.*'b'"):
        registry.register(Clash, plugin="b")


def test_the_digitalglobe_model_is_found_by_its_aliases():
    from geoblock.plugins import get_registry

    registry = get_registry()
    assert registry.get("quickbird") is registry.get("worldview") is registry.get("dg-rigorous")
