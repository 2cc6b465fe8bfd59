"""``geoblock mosaic``: mosaic GeoTIFF orthos of one CRS and resolution (atomic writes)."""

from __future__ import annotations

from typing import Any

import click

from geoblock.cli.options import (
    check_outputs,
    overwrite_opt,
    scheduler_opt,
    using_scheduler,
    write_options,
)

__all__ = ["mosaic"]


@click.command(short_help="Mosaic orthos (priority or feathering) with a contribution band.")
@click.argument("output", metavar="OUT")
@click.argument("orthos", metavar="ORTHO...", nargs=-1, required=True)
@click.option("--method", type=click.Choice(["priority", "feather"]), default="priority",
              show_default=True,
              help="priority: the first ORTHO with a valid pixel wins; feather: blend overlaps "
              "with weights growing with the distance to each ortho's nodata edge.")
@click.option("--feather", "feather_px", type=float, default=32.0, show_default=True,
              metavar="PX", help="Cap of the feathering weights, pixels (with --method feather).")
@click.option("--contribution", "contribution_path", metavar="CONTRIB.tif", default=None,
              help="Also write the contribution band: the 1-based index of the ORTHO each "
              "pixel came from (0: none), uint8.")
@click.option("--accuracy-layer", "accuracy_layer", metavar="[ACCURACY.tif]", is_flag=False,
              flag_value="", default=None,
              help="Write the mosaic's accuracy layer (default path: OUT's stem + "
              "'_accuracy.tif') from every ORTHO's accuracy layer (the '<stem>_accuracy.tif' "
              "'geoblock ortho --accuracy-layer' writes beside it, or --source-accuracy); an "
              "error when one is missing. Without this option the layer is written when every "
              "ORTHO has one beside it.")
@click.option("--source-accuracy", "source_accuracy", metavar="ACC.tif", multiple=True,
              help="The accuracy layer of each ORTHO, in the same order (repeat the option "
              "once per ORTHO); default the '<stem>_accuracy.tif' beside each.")
@click.option("--no-accuracy-layer", "no_accuracy", is_flag=True, default=False,
              help="Do not write the mosaic's accuracy layer.")
@click.option("--nodata", type=float, default=None,
              help="Output nodata; default the first ORTHO's nodata (else 0, NaN for floats).")
@click.option("--chunks", type=click.IntRange(min=1), default=1024, show_default=True,
              metavar="N", help="Chunk side, pixels (does not change the result).")
@click.option("--allow-empty", is_flag=True, default=False,
              help="Write OUT with a warning when no pixel is valid; by default that is an "
              "error and nothing is written.")
@scheduler_opt
@click.option("--cog", is_flag=True, default=False, help="Write a Cloud-Optimized GeoTIFF.")
@write_options
@overwrite_opt
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Show a progress bar.")
def mosaic(output: str, orthos: tuple[str, ...], method: str, feather_px: float,
           contribution_path: str | None, accuracy_layer: str | None,
           source_accuracy: tuple[str, ...], no_accuracy: bool,
           nodata: float | None, chunks: int, allow_empty: bool,
           scheduler: str, cog: bool, compress: str, level: int | None,
           creation_options: dict[str, str], overwrite: bool, progress: bool) -> None:
    """Mosaic the ORTHO GeoTIFFs (in priority order) onto their union grid and write OUT.

    The orthos must share CRS, resolution and pixel phase (nothing is reprojected or
    resampled) and their number of bands: 'geoblock ortho' with its default grid (or the
    same --crs and --res) gives such orthos for images of one sensor. With --method priority
    the first ORTHO with a valid pixel wins; with --method feather overlaps are blended, each
    ortho weighted by the distance (pixels, capped at --feather) to its nearest nodata pixel.
    OUT comes first (gdal_merge's -o, not gdalwarp's last argument): an OUT that is also an
    ORTHO is refused, and so is an OUT (or CONTRIB.tif) that exists, unless --overwrite, and an
    ORTHO that does not exist (named, with a reminder of the order when it is the last one).
    OUT (and CONTRIB.tif) are written under a temporary name and renamed at the end: a failed
    run, or one without any valid pixel (unless --allow-empty), leaves nothing there.

    The accuracy layers of the ORTHOs ('geoblock ortho --accuracy-layer', the predicted
    horizontal error per pixel, metres) are mosaicked with the same selection: the winning
    ORTHO's value (priority), or the feathering weights applied to the sources' errors,
    sum(w_k sigma_k) / sum(w_k) (an upper bound of the blend's error whatever the sources'
    correlation). They are found beside each ORTHO ('<stem>_accuracy.tif') or given with
    --source-accuracy; when only some ORTHOs have one, no accuracy layer is written and a
    warning names those without (an error with --accuracy-layer).

    \b
    Examples:
      geoblock mosaic mosaic.tif ortho1.tif ortho2.tif ortho3.tif
      geoblock mosaic mosaic.tif a.tif b.tif --method feather --feather 64 \\
          --contribution contrib.tif
    """
    from geoblock.errors import OutputExistsError
    from geoblock.io.images import write_ortho
    from geoblock.ortho.mosaic import mosaic as make_mosaic
    from geoblock.ortho.mosaic import open_ortho

    _check_orthos(output, orthos)
    layers, acc_path = _accuracy_inputs(output, orthos, accuracy_layer, source_accuracy,
                                        no_accuracy)
    try:
        check_outputs({"OUT": output, "--contribution": contribution_path,
                       "--accuracy-layer": acc_path},
                      {"ORTHO": orthos, "--source-accuracy": layers or None},
                      overwrite=overwrite)
    except OutputExistsError as exc:  # OUT given last, the gdalwarp habit, is a likely cause
        if str(exc).startswith("OUT "):
            raise OutputExistsError(f"{exc}; if {output!r} is an ortho given first by mistake: "
                                    "geoblock mosaic takes OUT first (geoblock mosaic OUT "
                                    "ORTHO...)") from None
        raise
    sources = [open_ortho(path, chunks=chunks) for path in orthos]
    accuracy = None if layers is None else [open_ortho(p, chunks=chunks) for p in layers]
    result = make_mosaic(sources, method=method, feather_px=feather_px, nodata=nodata,
                         chunks=chunks, accuracy=accuracy)
    write: dict[str, Any] = {
        "driver": "COG" if cog else "GTiff", "progress": progress,
        "compress": compress, "level": level, **creation_options}
    empty = "warn" if allow_empty else "error"
    with using_scheduler(scheduler) as where:
        write_ortho(result["mosaic"], output, empty=empty, scheduler=where, **write)
        if contribution_path is not None:  # all 0 exactly when the mosaic is empty
            write_ortho(result["contribution"].expand_dims(band=[1]), contribution_path,
                        empty="ignore", scheduler=where, **write)
        if acc_path is not None and layers is not None:
            from geoblock.ortho.accuracy import ACCURACY_DESCRIPTION

            write_ortho(result["accuracy"].expand_dims(band=[1]), acc_path, empty="ignore",
                        scheduler=where, tags=_mosaic_tags(layers, method, feather_px),
                        band_descriptions=[ACCURACY_DESCRIPTION], units="m", **write)
    rows, cols = result.sizes["y"], result.sizes["x"]
    click.echo(f"{output}: {rows} x {cols} px, {result.sizes['band']} band(s) from "
               f"{len(orthos)} orthos ({method})", err=True)
    if acc_path is not None and layers is not None:
        click.echo(f"{acc_path}: accuracy layer of the mosaic, metres", err=True)


def _accuracy_inputs(output: str, orthos: tuple[str, ...], asked: str | None,
                     given: tuple[str, ...], off: bool) -> tuple[list[str] | None, str | None]:
    """The ORTHOs' accuracy layers and the mosaic's layer path, or ``(None, None)``."""
    import os

    from geoblock.errors import GeoblockIOError
    from geoblock.io.outputs import is_virtual
    from geoblock.ortho.accuracy import accuracy_path

    if off:
        if asked is not None or given:
            raise click.UsageError("--no-accuracy-layer contradicts --accuracy-layer and "
                                   "--source-accuracy")
        return None, None
    if given and len(given) != len(orthos):
        raise click.UsageError(f"--source-accuracy: {len(given)} layers for {len(orthos)} "
                               "ORTHOs (give one per ORTHO, in the same order)")
    layers = list(given) if given else [accuracy_path(p) for p in orthos]
    missing = [o for o, p in zip(orthos, layers, strict=True)
               if not is_virtual(p) and not os.path.exists(p)]
    explicit = asked is not None or bool(given)
    if missing:
        which = ", ".join(f"{o!r} ({p!r})" for o, p in zip(orthos, layers, strict=True)
                          if o in missing)
        if explicit:
            raise GeoblockIOError(f"no accuracy layer for ORTHO {which}: every ORTHO needs one "
                                  "for the mosaic's ('geoblock ortho --accuracy-layer' writes "
                                  "it beside the ortho)")
        if len(missing) < len(orthos):
            import warnings

            from geoblock.models.uncertainty import AccuracyWarning

            warnings.warn(f"no accuracy layer for the mosaic: ORTHO {which} has none (the "
                          "other ORTHOs have one)", AccuracyWarning, stacklevel=2)
        return None, None
    return layers, accuracy_path(output) if not asked else asked


def _mosaic_tags(layers: list[str], method: str, feather_px: float) -> dict[str, str]:
    """The mosaic layer's metadata: the sources' meaning, their covariances and the rule."""
    from geoblock.io.rasters import cached_dataset
    from geoblock.ortho.accuracy import ACCURACY_TAG

    kinds: list[str] = []
    tags: dict[str, str] = {}
    for path in layers:
        mine = cached_dataset(str(path)).tags()
        tags.setdefault(ACCURACY_TAG, mine.get(ACCURACY_TAG, ""))
        kinds.append(mine.get(f"{ACCURACY_TAG}_COVARIANCE", "unknown"))
    rule = ("the first valid source's value" if method == "priority" else
            f"sum(w_k sigma_k) / sum(w_k), the image's feathering weights (cap {feather_px:g} "
            "px): an upper bound of the blend's error")
    tags.update({f"{ACCURACY_TAG}_UNIT": "m",
                 f"{ACCURACY_TAG}_COVARIANCE": ", ".join(dict.fromkeys(kinds)),
                 f"{ACCURACY_TAG}_MOSAIC": f"{method}: {rule}",
                 f"{ACCURACY_TAG}_SOURCES": "; ".join(layers)})
    return tags


def _check_orthos(output: str, orthos: tuple[str, ...]) -> None:
    """Every ORTHO exists (GDAL virtual paths are left to the reader); a missing last one is
    most likely an OUT given last, the gdalwarp habit: say that OUT comes first."""
    import os

    from geoblock.errors import GeoblockIOError
    from geoblock.io.outputs import is_virtual

    out = os.path.abspath(output)  # OUT among the ORTHOs: check_outputs names it
    missing = [p for p in orthos if not is_virtual(p) and not os.path.exists(p)
               and os.path.abspath(p) != out]
    if not missing:
        return
    if missing == [orthos[-1]]:
        order = " ".join([orthos[-1], output, *orthos[:-1]])
        raise GeoblockIOError(
            f"ORTHO {orthos[-1]!r} does not exist. If it is the output: geoblock mosaic takes "
            f"OUT first, as in 'geoblock mosaic {order}'")
    raise GeoblockIOError(f"ORTHO {missing[0]!r} does not exist"
                          + (f" (nor {len(missing) - 1} more)" if len(missing) > 1 else ""))
