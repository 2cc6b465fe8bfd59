"""geoblock-quickbird's hook implementations: the ``dg-rigorous`` model and the ISD reader."""

from __future__ import annotations

import geoblock

#: the model names this plugin's reader answers for (``None``: no model named)
MODEL_NAMES = (None, "dg-rigorous", "quickbird", "worldview")
#: the reader's options (:func:`geoblock_quickbird.model.dg_model`'s keywords)
OPTIONS = ("parameters", "accuracy_m", "height_range", "corrections", "tile", "check_rpb")


@geoblock.hookimpl
def geoblock_register_sensor_models(register):
    from geoblock_quickbird.model import DigitalGlobeModel

    register(DigitalGlobeModel)


@geoblock.hookimpl
def geoblock_read_sensor_model(path, model_name, options):
    """DigitalGlobe/Maxar support data -> the rigorous model (``dg-rigorous``).

    Answers for ``model_name`` None, ``"dg-rigorous"``, ``"quickbird"`` or ``"worldview"``
    and a combined ISD XML, a product's ``.IMD/.EPH/.ATT/.GEO/.RPB/.TIL`` file, a product
    directory or an image tile beside its support data (the tile's model, cropped from the
    full image). Support data without the physical sections (an RPC-only product) are left
    to geoblock-rpc when no model is named, and refused when ``dg-rigorous`` is asked for.
    Not ``trylast``: for an ISD that also holds an RPB the physical model wins; ask for
    ``model="rpc"`` to get the RPB.
    """
    if model_name not in MODEL_NAMES:
        return None
    from geoblock_quickbird.isd import IsdFormatError, find_isd

    found = find_isd(path)
    if found is None:
        if model_name is None:
            return None
        raise IsdFormatError(path, "(file)", f"model {model_name!r} needs DigitalGlobe support "
                                             "data (an <isd> XML or .IMD/.EPH/.ATT/.GEO files)")
    from geoblock_quickbird.isd import read_isd
    from geoblock_quickbird.model import dg_model

    try:
        isd = read_isd(path)
    except IsdFormatError as exc:
        if model_name is None and exc.missing:  # an RPC-only product: geoblock-rpc's
            return None
        raise
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise IsdFormatError(path, "(options)", f"unknown option(s) {unknown} for a "
                                                f"DigitalGlobe model; known: {list(OPTIONS)}")
    opts = dict(options)
    if "tile" not in opts and isd.tile(str(path)) is not None and not _is_support_file(path):
        opts["tile"] = str(path)
    return dg_model(isd, **opts)


def _is_support_file(path) -> bool:
    from geoblock.io.vsi import as_path

    p = as_path(path)
    return p.is_dir() or p.suffix.lower() in (".xml", ".imd", ".eph", ".att", ".geo", ".rpb",
                                              ".til")
