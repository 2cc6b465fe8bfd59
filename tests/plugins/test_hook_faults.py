"""A plugin whose read or write hook raises is skipped, named, and does not break the others.

The rule (geoblock.plugins.call_firstresult): a ``GeoblockError`` raised by an implementation is
its answer ("I recognised this file and it is invalid") and reaches the user; any other
exception is a bug of that plugin, skipped with a ``PluginWarning`` naming it.
"""

from __future__ import annotations

import warnings

import pytest

import geoblock
from geoblock.errors import ModelFormatError, PluginWarning, UnsupportedFormatError
from geoblock.hookspecs import hookimpl
from geoblock.plugins import call_firstresult, create_plugin_manager


class _FaultyReader:
    """Asked first (tryfirst), raises a plugin bug on every file."""

    __name__ = "faulty-reader"

    @hookimpl(tryfirst=True)
    def geoblock_read_sensor_model(self, path, model_name, options):
        raise RuntimeError("reader bug in faulty-reader")


class _StrictReader:
    """Recognises every file and finds it malformed: a GeoblockError, the user's answer."""

    __name__ = "strict-reader"

    @hookimpl(tryfirst=True)
    def geoblock_read_sensor_model(self, path, model_name, options):
        raise ModelFormatError(f"{path}: field LINE_OFF is malformed")


class _FaultyWriter:
    __name__ = "faulty-writer"

    @hookimpl(tryfirst=True)
    def geoblock_write_sensor_model(self, model, path, format, options):
        raise KeyError("writer bug in faulty-writer")


class _Declines:
    """A well-behaved reader that recognises nothing."""

    __name__ = "declines"

    @hookimpl
    def geoblock_read_sensor_model(self, path):
        return None


@pytest.fixture
def rpc_file(data_dir):
    path = data_dir / "gdal-autotest" / "gcore" / "data" / "md_dg.RPB"
    if not path.is_file():
        pytest.skip(f"{path} is missing")
    pytest.importorskip("geoblock_rpc", reason="the geoblock-rpc plugin is not installed")
    return path


def _use(monkeypatch, *plugins):
    """The process-wide plugin manager, plus ``plugins`` (registered last)."""
    pm = create_plugin_manager(entry_points=True, plugins=list(plugins))
    monkeypatch.setattr("geoblock.plugins.get_plugin_manager", lambda: pm)
    return pm


def test_a_raising_reader_is_skipped_and_named(monkeypatch, rpc_file):
    pm = _use(monkeypatch, _FaultyReader())
    assert "faulty-reader" in [n for n, _ in pm.list_name_plugin()]
    with pytest.warns(PluginWarning, match=r"'faulty-reader'.*RuntimeError: reader bug") as rec:
        model = geoblock.open_model(rpc_file)
    assert model.name == "rpc"
    assert len([w for w in rec if issubclass(w.category, PluginWarning)]) == 1
    assert "geoblock_read_sensor_model" in str(rec[0].message)


def test_reading_without_the_faulty_plugin_gives_the_same_model(monkeypatch, rpc_file):
    _use(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PluginWarning)
        clean = geoblock.open_model(rpc_file)
    _use(monkeypatch, _FaultyReader())
    with pytest.warns(PluginWarning):
        isolated = geoblock.open_model(rpc_file)
    assert isolated.to_dict() == clean.to_dict()


def test_a_geoblock_error_from_a_reader_still_reaches_the_user(monkeypatch, rpc_file):
    _use(monkeypatch, _StrictReader())
    with warnings.catch_warnings():
        warnings.simplefilter("error", PluginWarning)  # not a plugin bug: no warning
        with pytest.raises(ModelFormatError, match="LINE_OFF is malformed") as info:
            geoblock.open_model(rpc_file)
    assert any("strict-reader" in note for note in getattr(info.value, "__notes__", []))


def test_only_faulty_readers_unsupported_format_names_them(monkeypatch, tmp_path):
    monkeypatch.setattr("geoblock.plugins.DEFAULT_PLUGINS", ())
    pm = create_plugin_manager(entry_points=False, plugins=[_Declines(), _FaultyReader()])
    monkeypatch.setattr("geoblock.plugins.get_plugin_manager", lambda: pm)
    path = tmp_path / "scene.xyz"
    path.write_text("nothing\n")
    with pytest.warns(PluginWarning, match="faulty-reader"):
        with pytest.raises(UnsupportedFormatError, match=r"faulty-reader \(RuntimeError"):
            geoblock.open_model(path)


def test_a_raising_writer_is_skipped_and_the_json_writer_answers(
    monkeypatch, tmp_path, affine_camera
):
    _use(monkeypatch, _FaultyWriter())
    out = tmp_path / "model.json"
    with pytest.warns(PluginWarning, match=r"'faulty-writer'.*KeyError"):
        assert geoblock.write_model(affine_camera, out) == out
    assert geoblock.open_model(out) == affine_camera


def test_the_call_order_is_pluggys(monkeypatch):
    """Implementations are asked in the order pluggy itself would use."""
    calls = []

    def plugin(name, **opts):
        class P:
            __name__ = name

            @hookimpl(**opts)
            def geoblock_read_sensor_model(self, path):
                calls.append(name)

        return P()

    monkeypatch.setattr("geoblock.plugins.DEFAULT_PLUGINS", ())
    pm = create_plugin_manager(
        entry_points=False,
        plugins=[plugin("last", trylast=True), plugin("a"), plugin("b"),
                 plugin("first", tryfirst=True)],
    )
    pm.hook.geoblock_read_sensor_model(path=None, model_name=None, options={})
    expected = list(calls)
    calls.clear()
    assert call_firstresult(
        pm, "geoblock_read_sensor_model", path=None, model_name=None, options={}
    ) == (None, [])
    assert calls == expected == ["first", "b", "a", "last"]


def test_keyboard_interrupt_is_not_swallowed(monkeypatch):
    class Interrupts:
        __name__ = "interrupts"

        @hookimpl
        def geoblock_read_sensor_model(self, path):
            raise KeyboardInterrupt

    monkeypatch.setattr("geoblock.plugins.DEFAULT_PLUGINS", ())
    pm = create_plugin_manager(entry_points=False, plugins=[Interrupts()])
    with pytest.raises(KeyboardInterrupt):
        call_firstresult(pm, "geoblock_read_sensor_model", path=None, model_name=None,
                         options={})
