"""Plugin loading through real entry points: fake distributions installed on sys.path."""

from __future__ import annotations

import sys
import textwrap
import warnings

import pytest

import geoblock
from geoblock.errors import DuplicateModelError, PluginWarning
from geoblock.models.registry import build_registry
from geoblock.plugins import create_plugin_manager, list_plugins

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
    assert {"image-correction", "synthetic-affine", "synthetic-pushbroom"} <= set(get_registry())
