"""geoblock-rpc's hook implementations: the ``rpc`` model, its readers and writers."""

from __future__ import annotations

import warnings
from pathlib import Path

import geoblock
from geoblock.errors import GeoblockWarning, ModelFormatError
from geoblock_rpc.model import RpcModel


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    register(RpcModel)


@geoblock.hookimpl(trylast=True)
def geoblock_read_sensor_model(path, model_name, options):
    """Any RPC container :func:`geoblock_rpc.readers.read_rpc` recognises -> :class:`RpcModel`.

    Generic (``trylast``): physical-model plugins reading the same metadata answer first.
    Returns ``None`` for files that carry no recognisable RPC container, or when another
    model than ``"rpc"`` is asked for. Options: ``crop_offset``, ``crop_from_geotransform``,
    ``image`` (see :mod:`geoblock_rpc.readers`).
    """
    if (model_name is not None and model_name != RpcModel.name) or Path(path).is_dir():
        return None
    from geoblock_rpc.readers import _read

    result = _read(path, dict(options))
    if result is None:
        return None
    rpc, shape, _extra = result
    return RpcModel(rpc, shape)


#: a refitted RPC (a correction that does not fold exactly) is written only when it reproduces
#: the corrected model to this many pixels on the check grid (option ``max_refit_error_px``)
MAX_REFIT_ERROR_PX = 1e-3


@geoblock.hookimpl(trylast=True)
def geoblock_write_sensor_model(model, path, format, options):
    """An ``RpcModel``, or an ``ImageCorrection`` wrapping one (RPCV-0/RPCV-1 ...), as
    ``"rpc-txt"`` (GDAL ``_RPC.TXT``), ``"rpb"`` or ``"gtiff"`` tags.

    A correction is folded into the RPC00B coefficients exactly where the algebra allows
    (:mod:`geoblock_rpc.fold`), else the RPC is refitted to the corrected model and written
    when its error on the check grid is at most ``max_refit_error_px`` (default 1e-3 px). The
    fold report is issued as a :class:`~geoblock.errors.GeoblockWarning` so that callers (the
    ``geoblock refine`` command) show it.
    """
    from geoblock_rpc.fold import is_rpc_based, rpc_for
    from geoblock_rpc.writers import WRITERS

    if format not in WRITERS or not is_rpc_based(model):
        return None
    options = dict(options)
    limit = float(options.pop("max_refit_error_px", MAX_REFIT_ERROR_PX))
    fold_options = {k: options.pop(k) for k in ("grid", "regularization") if k in options}
    if isinstance(model, RpcModel):
        WRITERS[format](model, path, **options)
        return True
    rpc, report = rpc_for(model, **fold_options)
    if not report.exact and not report.max_error_px <= limit:
        raise ModelFormatError(
            f"{path}: the order-{model.order} correction does not fold into RPC00B exactly and "
            f"the refitted RPC misses the corrected model by {report.max_error_px:.3g} px "
            f"(> max_refit_error_px={limit:g}); write the model as JSON instead ({report})"
        )
    base = model
    while not isinstance(base, RpcModel):
        base = base.model
    folded = RpcModel(rpc, model.shape, domain_limit=base.domain_limit,
                      height_limit=base.height_limit)
    WRITERS[format](folded, path, **options)
    warnings.warn(f"{path}: {report}", GeoblockWarning, stacklevel=2)
    return True
