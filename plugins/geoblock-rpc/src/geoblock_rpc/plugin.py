"""geoblock-rpc's hook implementations: the ``rpc`` and ``rfm`` models, the RPC readers and
writers, and the ``geoblock fit-rfm`` and ``geoblock export-rpc`` commands.

The writer exports **any** sensor model as an RPC00B through :func:`geoblock_rpc.export.export_rpc`
and reports what it did (exact, folded or fitted) by an
:class:`~geoblock_rpc.export.RpcExportWarning`.

Cheap to import (geoblock imports it whenever it lists its plugins, ``geoblock --help``
included): the models, readers and writers are imported inside the hooks.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import geoblock

if TYPE_CHECKING:  # pragma: no cover
    import click

    from geoblock.models.protocol import SensorModel
    from geoblock_rpc.model import RpcModel


@geoblock.hookimpl
def geoblock_register_sensor_models(register: Callable[[type[SensorModel]], None]) -> None:
    from geoblock_rpc.model import RpcModel
    from geoblock_rpc.rfm import RfmModel

    register(RpcModel)
    register(RfmModel)


@geoblock.hookimpl
def geoblock_register_commands(cli: click.Group) -> None:
    """``geoblock export-rpc`` and ``geoblock fit-rfm`` (:mod:`geoblock_rpc.cli`)."""
    from geoblock_rpc.cli import export_rpc_command, fit_rfm_command

    cli.add_command(export_rpc_command)
    cli.add_command(fit_rfm_command)


@geoblock.hookimpl(trylast=True)
def geoblock_read_sensor_model(
    path: Path, model_name: str | None, options: Mapping[str, Any]
) -> RpcModel | None:
    """Any RPC container :func:`geoblock_rpc.readers.read_rpc` recognises -> :class:`RpcModel`.

    Generic (``trylast``): physical-model plugins reading the same metadata answer first.
    Returns ``None`` for files that carry no recognisable RPC container, or when another
    model than ``"rpc"`` is asked for. Options: ``crop_offset``, ``crop_from_geotransform``,
    ``image`` (see :mod:`geoblock_rpc.readers`).
    """
    from geoblock_rpc.model import RpcModel

    from geoblock.io.vsi import as_path

    path = as_path(path)  # a VsiPath stays one: Path() would collapse its "//"
    if (model_name is not None and model_name != RpcModel.name) or path.is_dir():
        return None
    from geoblock_rpc.readers import _read

    result = _read(path, dict(options))
    if result is None:
        return None
    rpc, shape, extra = result
    return RpcModel(rpc, shape, source_ids=extra.get("source_ids"))


@geoblock.hookimpl(trylast=True)
def geoblock_write_sensor_model(
    model: SensorModel, path: Path, format: str, options: Mapping[str, Any]
) -> bool | None:
    """Any model as ``"rpc-txt"`` (GDAL ``_RPC.TXT``), ``"rpb"`` or ``"gtiff"`` tags.

    An ``RpcModel`` is written as it is. Any other model goes through :func:`export_rpc`: an
    image correction of an RPC is folded into the RPC00B coefficients exactly where the
    algebra allows (:mod:`geoblock_rpc.fold`), else refitted; any other model is fitted
    (:func:`geoblock_rpc.fit.fit_rpc`). An approximate RPC is written only when its maximum
    error on the check grid is at most ``max_error_px`` (default 1e-3 px for a refitted
    correction, 0.5 px for a fitted model; ``max_refit_error_px`` is the former name).
    Options ``grid`` and ``regularization`` go to the fit; the others to the writer. The
    report is issued as an :class:`RpcExportWarning` (a
    :class:`~geoblock.errors.GeoblockWarning`) so that callers show it.
    """
    from geoblock_rpc.export import EXPORT_OPTIONS, RpcExportWarning, export_rpc
    from geoblock_rpc.writers import WRITERS

    if format not in WRITERS:
        return None
    options = dict(options)
    export_options = {k: options.pop(k) for k in EXPORT_OPTIONS if k in options}
    rpc_model, report = export_rpc(model, label=str(path), **export_options)
    WRITERS[format](rpc_model, path, **options)
    if report.method != "identity":
        warnings.warn(RpcExportWarning(f"{path}: {report.message}", report), stacklevel=2)
    return True
