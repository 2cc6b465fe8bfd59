"""The ``geoblock`` click group: built-in commands, plugin commands, errors and warnings.

* :func:`build_cli` makes the group, optionally from a given plugin manager (tests, embedding);
  :data:`cli` is one built over the process-wide plugin manager and :func:`main` the
  console-script entry point.
* Built-in commands are added first, as :class:`LazyCommand` stand-ins (name and short help,
  from :data:`BUILTIN_COMMANDS`): a command's module is imported when the command runs or
  shows its own help, so ``geoblock --help`` imports none of them. Plugin commands come from
  each plugin's ``geoblock_register_commands(cli)``, called one plugin at a time inside
  ``try``: a plugin whose hook raises is rolled back, reported with a
  :class:`~geoblock.errors.PluginWarning` and replaced by a :class:`BrokenCommand` stub that
  explains the failure (click-plugins' ``BrokenCommand``, as vendored by rasterio). A plugin
  cannot replace an existing command. Plugin commands are loaded lazily, the first time the
  group lists or resolves a command, so that ``-q`` already applies to the warnings of plugin
  loading.
* Any exception (a :class:`~geoblock.errors.GeoblockError` or an unexpected one) becomes one
  ``Error: <message>`` line on standard error and exit code 1; ``--verbose`` prints the
  traceback first. click's usage errors keep click's behaviour (exit code 2).
* Warnings are printed as one ``Warning: <message>`` line each; ``--quiet`` drops geoblock's.
* :func:`main` handles ``SIGTERM`` (what ``timeout``, ``kill`` and batch schedulers send) like
  ``Ctrl-C``: the signal raises :class:`Terminated` (a ``KeyboardInterrupt``) in the main
  thread, so every ``finally`` and context manager runs and removes its temporary files;
  ``Aborted!`` is printed and the exit code is 143 (128 + SIGTERM). ``Ctrl-C`` (``SIGINT``)
  does the same with the exit code 130 (128 + SIGINT), where click alone exits 1.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import signal
import threading
import traceback
import warnings
from collections.abc import Iterator, Sequence
from typing import Any, TextIO

import click

from geoblock import plugins as _plugins
from geoblock.errors import (
    GeoblockDeprecationWarning,
    GeoblockError,
    GeoblockWarning,
    PluginError,
    PluginWarning,
)

__all__ = [
    "BUILTIN_COMMANDS",
    "BrokenCommand",
    "GeoblockGroup",
    "LazyCommand",
    "Terminated",
    "build_cli",
    "cli",
    "main",
]

_GEOBLOCK_WARNINGS = (GeoblockWarning, GeoblockDeprecationWarning)

#: click's own control flow: never turned into an ``Error:`` line by geoblock.
_CLICK_FLOW = (
    click.exceptions.ClickException,
    click.exceptions.Exit,
    click.exceptions.Abort,
    EOFError,
)


def _one_line(text: str) -> str:
    return " ".join(part.strip() for part in str(text).splitlines() if part.strip())


def error_message(exc: BaseException) -> str:
    """The one-line message shown for ``exc`` after ``Error:``."""
    if isinstance(exc, GeoblockError):
        text = _one_line(str(exc)) or type(exc).__name__
    elif isinstance(exc, OSError) and exc.strerror:
        text = _one_line(str(exc))  # "[Errno 2] No such file or directory: 'out/x.csv'"
    else:
        detail = _one_line(str(exc))
        text = f"{type(exc).__name__}: {detail}" if detail else type(exc).__name__
    return text


#: built-in command -> (module, attribute, the short help ``geoblock --help`` shows for it).
#: A command's module is imported only when the command runs or shows its own help, so that
#: ``geoblock --help`` imports none of them (numpy, numba, PROJ...). The short helps are the
#: commands' own, copied: ``tests/cli/test_cli_lazy.py`` fails when one differs.
BUILTIN_COMMANDS: dict[str, tuple[str, str, str]] = {
    "plugins": ("geoblock.cli.plugins", "plugins",
                "List plugins, their hooks, models and commands."),
    "info": ("geoblock.cli.info", "info",
             "Describe a sensor model: size, parameters, footprint, GSD."),
    "project": ("geoblock.cli.project", "project",
                "Ground points (lon, lat, h) -> image (row, col)."),
    "backproject": ("geoblock.cli.project", "backproject",
                    "Image points (row, col) at height h -> ground (lon, lat)."),
    "refine": ("geoblock.cli.refine", "refine",
               "Fit an image correction (RPCV-0/RPCV-1/order 2) to GCPs."),
    "adjust": ("geoblock.cli.adjust", "adjust",
               "Adjust a block of images (MBA, DG, RFM, RPCV-0/1) with GCPs, TPs, DEM."),
    "localize": ("geoblock.cli.localize", "localize",
                 "Image points (row, col) -> ground (lon, lat, h) on a DEM."),
    "match": ("geoblock.cli.match", "match",
              "Tie points between images, guided by their sensor models (SIFT)."),
    "triangulate": ("geoblock.cli.triangulate", "triangulate",
                    "Points measured in 2+ images -> ground (lon, lat, h), no DEM."),
    "dem-info": ("geoblock.cli.dem_info", "dem_info",
                 "Describe a DEM: extent, CRS, vertical datum, heights."),
    "ortho": ("geoblock.cli.ortho", "ortho",
              "Orthorectify an image with its sensor model and a DEM."),
    "mosaic": ("geoblock.cli.mosaic", "mosaic",
               "Mosaic orthos (priority or feathering) with a contribution band."),
    "simulate": ("geoblock.cli.simulate", "simulate",
                 "Simulate a block with known truth (preset or scenario TOML)."),
    "demo": ("geoblock.cli.demo", "demo",
             "The whole pipeline on a simulated block: adjust, orthorectify, mosaic, report."),
}


class LazyCommand(click.Command):
    """A built-in command's stand-in until it is run: its name and short help only
    (:data:`BUILTIN_COMMANDS`). :meth:`GeoblockGroup.get_command` replaces it with the real
    command, importing its module, the first time the command is resolved."""

    def __init__(self, name: str, module: str, attribute: str, short_help: str) -> None:
        super().__init__(name, short_help=short_help)
        self.module = module
        self.attribute = attribute

    def load(self) -> click.Command:
        """The real command (its module imported)."""
        command = getattr(importlib.import_module(self.module), self.attribute)
        if not isinstance(command, click.Command):  # pragma: no cover - a wrong table entry
            raise TypeError(f"{self.module}.{self.attribute} is not a click command")
        return command


class BrokenCommand(click.Command):
    """Stands in for the commands of a plugin whose ``geoblock_register_commands`` raised.

    Listed in ``geoblock --help`` with a short note; running it fails with one ``Error:`` line
    naming the plugin and the original exception (``geoblock -v`` shows its traceback).
    """

    def __init__(self, name: str, plugin_name: str, exc: BaseException) -> None:
        self.plugin_name = plugin_name
        self.exc = exc
        reason = error_message(exc)
        super().__init__(
            name,
            help=(
                f"Warning: geoblock plugin {plugin_name!r} failed to add its commands, so "
                f"they are unavailable: {reason}\n\nReinstall or update the plugin; "
                f"'geoblock -v {name}' shows the traceback."
            ),
            short_help="(broken plugin: run it for details)",
            context_settings={"ignore_unknown_options": True, "allow_extra_args": True},
        )

    def invoke(self, ctx: click.Context) -> Any:
        raise PluginError(
            f"geoblock plugin {self.plugin_name!r} failed to add its commands: "
            f"{error_message(self.exc)}",
            plugin_name=self.plugin_name,
        ) from self.exc


class GeoblockGroup(click.Group):
    """The ``geoblock`` group: lazy plugin commands, one-line errors and warnings.

    Parameters
    ----------
    plugin_manager : pluggy.PluginManager, optional
        Where plugin commands come from; by default :func:`geoblock.plugins.get_plugin_manager`
        (looked up when first needed).
    """

    def __init__(self, *args: Any, plugin_manager: Any = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._plugin_manager = plugin_manager
        self._plugins_loaded = False
        #: plugin name -> names of the commands it added
        self.plugin_commands: dict[str, list[str]] = {}
        #: plugin name -> one-line reason its ``geoblock_register_commands`` failed
        self.broken_plugins: dict[str, str] = {}
        self.verbose = False
        self.quiet = False

    # ------------------------------------------------------------------ plugins
    @property
    def plugin_manager(self) -> Any:
        """The plugin manager given to :func:`build_cli`, else the process-wide one."""
        if self._plugin_manager is not None:
            return self._plugin_manager
        return _plugins.get_plugin_manager()

    @property
    def explicit_plugin_manager(self) -> Any:
        """The plugin manager given to :func:`build_cli`, or ``None`` for the process-wide one."""
        return self._plugin_manager

    def load_plugin_commands(self) -> None:
        """Call every plugin's ``geoblock_register_commands(cli)`` once, each in isolation."""
        if self._plugins_loaded:
            return
        self._plugins_loaded = True
        hook = self.plugin_manager.hook.geoblock_register_commands
        for impl in reversed(hook.get_hookimpls()):  # the order pluggy itself calls them in
            self._register_from(impl)

    def _register_from(self, impl: Any) -> None:
        name = impl.plugin_name
        before = dict(self.commands)
        try:
            kwargs = {"cli": self}
            impl.function(*[kwargs[a] for a in impl.argnames])
        except Exception as exc:  # third-party code must not take the command line down
            self.commands.clear()
            self.commands.update(before)
            reason = error_message(exc)
            self.broken_plugins[name] = reason
            warnings.warn(
                f"geoblock plugin {name!r} failed to add its commands and was skipped: {reason}",
                PluginWarning,
                stacklevel=2,
            )
            if name not in self.commands:
                self.add_command(BrokenCommand(name, name, exc))
            return
        for cmd_name, cmd in before.items():
            if self.commands.get(cmd_name) is not cmd:
                self.commands[cmd_name] = cmd
                warnings.warn(
                    f"geoblock plugin {name!r} tried to replace the command {cmd_name!r}; "
                    "the existing command was kept",
                    PluginWarning,
                    stacklevel=2,
                )
        self.plugin_commands[name] = [n for n in self.commands if n not in before]

    def list_commands(self, ctx: click.Context) -> list[str]:
        self.load_plugin_commands()
        return super().list_commands(ctx)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        self.load_plugin_commands()
        command = super().get_command(ctx, cmd_name)
        if isinstance(command, LazyCommand):
            command = self.commands[cmd_name] = command.load()
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The commands' list of ``geoblock --help``, as click writes it, but from the
        stand-ins' short helps: listing the built-in commands imports none of them."""
        self.load_plugin_commands()
        listed = [(name, self.commands.get(name)) for name in self.list_commands(ctx)]
        commands = [(name, cmd) for name, cmd in listed if cmd is not None and not cmd.hidden]
        if commands:
            limit = formatter.width - 6 - max(len(name) for name, _ in commands)
            rows = [(name, cmd.get_short_help_str(limit)) for name, cmd in commands]
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    # ------------------------------------------------------------------ errors and warnings
    def main(self, *args: Any, **kwargs: Any) -> Any:
        self.verbose = False
        self.quiet = False
        with warnings.catch_warnings():
            for category in _GEOBLOCK_WARNINGS:
                warnings.filterwarnings("always", category=category)
            warnings.showwarning = self._show_warning
            return super().main(*args, **kwargs)

    def _show_warning(self, message: Warning | str, category: type[Warning], filename: str,
                      lineno: int, file: TextIO | None = None, line: str | None = None) -> None:
        if issubclass(category, _GEOBLOCK_WARNINGS):
            if self.quiet:
                return
            text = _one_line(str(message))
        else:
            text = f"{category.__name__}: {_one_line(str(message))}"
        click.echo(f"Warning: {text}", err=True)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except _CLICK_FLOW:
            raise
        except Exception as exc:
            if isinstance(exc, OSError) and exc.errno == errno.EPIPE:
                raise  # click silences a closed pipe (geoblock ... | head)
            message = error_message(exc)
            if self.verbose:
                click.echo("".join(traceback.format_exception(exc)), err=True, nl=False)
            elif not isinstance(exc, GeoblockError | OSError):
                message += " (run 'geoblock --verbose ...' to see the traceback)"
            raise click.ClickException(message) from exc


def _set_flag(ctx: click.Context, param: click.Parameter, value: bool) -> bool:
    root = ctx.find_root().command
    if value and isinstance(root, GeoblockGroup):
        setattr(root, param.name or "", True)
    return value


def _version() -> str:
    import geoblock

    return geoblock.__version__


def build_cli(plugin_manager: Any = None) -> GeoblockGroup:
    """A new ``geoblock`` command group.

    Parameters
    ----------
    plugin_manager : pluggy.PluginManager, optional
        Where plugin commands (and ``geoblock plugins``' listing) come from; default the
        process-wide :func:`geoblock.plugins.get_plugin_manager`. Tests pass
        ``geoblock.plugins.create_plugin_manager(entry_points=False, plugins=[...])``.

    Returns
    -------
    GeoblockGroup
    """
    @click.group(
        cls=GeoblockGroup,
        name="geoblock",
        plugin_manager=plugin_manager,
        context_settings={"help_option_names": ["-h", "--help"]},
    )
    @click.version_option(
        version=_version(), prog_name="geoblock", message="%(prog)s %(version)s"
    )
    @click.option(
        "-v", "--verbose", is_flag=True, is_eager=True, expose_value=False,
        callback=_set_flag, help="Show the full traceback of errors.",
    )
    @click.option(
        "-q", "--quiet", is_flag=True, is_eager=True, expose_value=False,
        callback=_set_flag, help="Do not show geoblock's warnings.",
    )
    def cli() -> None:
        """geoblock: geometric processing of optical satellite images.

        Sensor models come from plugins ('geoblock plugins' lists them). Coordinates follow
        geoblock's conventions: lon, lat in degrees and h in metres above the WGS84 ellipsoid;
        row, col in pixels with (0, 0) at the centre of the first pixel.

        \b
        Examples:
          geoblock plugins
          geoblock info scene.json
          geoblock project scene.json gcps.csv -o gcps_image.csv
          geoblock -v backproject scene.json measures.csv
        """

    for name, (module, attribute, short_help) in BUILTIN_COMMANDS.items():
        cli.add_command(LazyCommand(name, module, attribute, short_help))
    return cli


#: The group over the process-wide plugin manager (its plugin commands load on first use), for
#: ``CliRunner().invoke(cli, [...])`` and for embedding; :func:`main` builds a fresh one per run.
cli = build_cli()


class Terminated(KeyboardInterrupt):
    """Raised in the main thread when :func:`main` receives ``SIGTERM``.

    A ``KeyboardInterrupt``, so that everything which cleans up after ``Ctrl-C`` (``finally``
    blocks, :func:`geoblock.io._atomic.atomic_path`, ``write_ortho``'s temporaries, dask's
    schedulers) does the same after ``SIGTERM``.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class _SignalState:
    received: int | None = None


def _exit_code(signum: int) -> int:
    return 128 + signum


@contextlib.contextmanager
def _terminate_as_interrupt() -> Iterator[_SignalState]:
    """While inside, ``SIGTERM`` raises :class:`Terminated` and ``SIGINT`` (``Ctrl-C``) a
    ``KeyboardInterrupt`` in the main thread, and the signal is recorded in the state.

    Recording ``SIGINT`` is what lets :func:`main` exit with 130 where click says 1. Nothing is
    installed outside the main thread, nor for a signal that is ignored (the caller asked for
    it: ``nohup``, a shell's background job). A second signal during the clean-up is ignored,
    so that the clean-up completes (a scheduler's later ``SIGKILL`` still ends the process).
    The previous handlers are restored on leaving.
    """
    state = _SignalState()
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def handler(signum: int, frame: Any) -> None:
        if state.received is not None:
            return  # already unwinding
        state.received = signum
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(signum)

    previous: dict[int, Any] = {}
    for name in ("SIGTERM", "SIGINT"):
        signum = getattr(signal, name, None)
        if signum is None or signal.getsignal(signum) is signal.SIG_IGN:
            continue
        try:
            previous[signum] = signal.signal(signum, handler)
        except (ValueError, OSError):  # not allowed here (an embedding interpreter)
            continue
    try:
        yield state
    finally:
        for signum, before in previous.items():
            signal.signal(signum, before if before is not None else signal.SIG_DFL)


def main(args: Sequence[str] | None = None) -> Any:
    """Console-script entry point: ``geoblock [OPTIONS] COMMAND [ARGS]...``.

    ``Ctrl-C`` (``SIGINT``) and ``SIGTERM`` remove temporary files and print ``Aborted!``; the
    exit code is 128 + the signal's number, as a shell reports a process the signal ended:
    130 for ``Ctrl-C``, 143 for ``SIGTERM`` (click alone would exit 1).
    """
    with _terminate_as_interrupt() as state:
        try:
            return build_cli().main(args=args, prog_name="geoblock")
        except SystemExit:
            if state.received is not None:  # click turned the interrupt into Abort, exit 1
                raise SystemExit(_exit_code(state.received)) from None
            raise
        except KeyboardInterrupt:
            if state.received is None:
                raise
            # the signal came outside click's main (while building the command line)
            click.echo("Aborted!", err=True)
            raise SystemExit(_exit_code(state.received)) from None
