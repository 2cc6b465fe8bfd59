"""``geoblock match``: tie points between images, guided by their sensor models and a DEM."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import click

from geoblock.cli.options import (
    check_outputs,
    dem_options,
    deprecated_aliases,
    force_opt,
    no_crop_opt,
    open_dem_arg,
    output_opt,
    overwrite_opt,
    positive_float,
    scheduler_opt,
    using_scheduler,
)

if TYPE_CHECKING:
    from geoblock.match.pipeline import MatchImage

__all__ = ["match"]


def _unit_interval(ctx: click.Context, param: click.Parameter, value: float | None
                   ) -> float | None:
    if value is not None and not (0 < value <= 1):
        raise click.BadParameter(f"{value!r} is not in (0, 1].", ctx, param)
    return value


@deprecated_aliases(id="--image-id", sigma="--sigma-px")
@click.command(short_help="Tie points between images, guided by their sensor models (SIFT).")
@click.argument("inputs", metavar="IMAGE IMAGE... | BLOCK.toml", nargs=-1, required=True)
@output_opt
@click.option("--model", "models", metavar="MODEL_FILE", multiple=True,
              help="Sensor-model file of an IMAGE, once per IMAGE in the same order; default: "
              "the model stored in each IMAGE (e.g. its GeoTIFF RPC tags).")
@click.option("--image-id", "ids", metavar="ID", multiple=True,
              help="Image id written in the 'image' column, once per IMAGE in the same "
              "order; default the file names without extension (a block file's ids).")
@dem_options(required=False, required_help=" Required with IMAGEs; default the block file's "
             "[dem].")
@click.option("--dem-sigma", type=float, metavar="M", default=None, callback=positive_float,
              help="Accuracy of the DEM's heights (1 sigma, metres): the first pass looks "
              "three times its height parallax along the epipolar direction. Default the "
              "block file's dem.sigma, else 10.")
@no_crop_opt
@force_opt
@click.option("--search", "search_px", type=float, metavar="PX", default=None,
              callback=positive_float,
              help="How far the models may disagree, pixels: radius of the first pass' "
              "window. Default three times the accuracy the models state, else 60.")
@click.option("--max-keypoints", type=click.IntRange(min=1), default=20000, show_default=True,
              metavar="N", help="SIFT keypoints per image, spread over 128 px cells.")
@click.option("--contrast-threshold", type=float, default=0.02, show_default=True,
              metavar="C", callback=positive_float,
              help="SIFT's contrast threshold (lower: more keypoints in flat areas).")
@click.option("--ratio", type=float, default=0.8, show_default=True, metavar="R",
              callback=_unit_interval, help="Lowe's ratio test, inside the search window.")
@click.option("--min-score", type=click.FloatRange(-1.0, 1.0), default=0.7, show_default=True,
              metavar="NCC", help="Smallest correlation of a refined match.")
@click.option("--order", type=click.IntRange(0, 2), default=1, show_default=True,
              help="Order of the image-space bias between the models (0 shift, 1 affine).")
@click.option("-k", "k_sigma", type=float, default=3.0, show_default=True, metavar="K",
              callback=positive_float,
              help="Rejection threshold of the epipolar and height tests, robust sigmas.")
@click.option("--sigma-px", "sigma_px", type=float, metavar="PX", default=None,
              callback=positive_float,
              help="The sigma column written, pixels; default estimated per pair from the "
              "matches' scatter across the epipolar direction.")
@click.option("--ictp-share", type=click.FloatRange(0.0, 0.5), default=0.0, show_default=True,
              metavar="FRACTION",
              help="Write this share of the tie points as ICTPs (kind ictp): measured but not "
              "adjusted; 'geoblock adjust' ray-traces them onto the DEM from each image and "
              "reports the images' relative accuracy (Teo et al.'s independent check tie "
              "points).")
@click.option("--id-prefix", default="tp", show_default=True, metavar="TEXT",
              help="Tie-point ids are TEXT00000, TEXT00001, ...")
@click.option("--reference", "reference", metavar="ORTHO", default=None,
              help="Also measure ground control points on this reference orthoimage (any "
              "georeferenced raster: a national ortho, Sentinel-2's GRI, an earlier adjusted "
              "mosaic): each image is warped onto its grid through its model and the DEM, "
              "matched by correlation, and each match becomes a GCP (kind gcp, source "
              "reference:<file name>). Default: the block file's [reference].")
@click.option("--reference-accuracy", "reference_accuracy", type=float, metavar="CE90_M",
              default=None, callback=positive_float,
              help="The reference's absolute accuracy, CE90 in metres: every control point is "
              "weighted by it. Required with --reference unless the block file's "
              "[reference] table gives accuracy_ce90_m.")
@click.option("--reference-local-accuracy", "reference_local_accuracy", type=float,
              metavar="CE90_M", default=None,
              help="The reference's local (point-to-point) accuracy, CE90 in metres, added to "
              "each control point's own sigma; --reference-accuracy is an error common to all "
              "its points. Default the block file's reference.local_accuracy_ce90_m, else 0 "
              "(the matching's precision alone).")
@click.option("--reference-band", type=click.IntRange(min=1), default=None, metavar="N",
              help="Band of the reference matched (1-based). Default the block file's "
              "reference.band, else 1.")
@click.option("--ground-output", metavar="CSV", default=None,
              help="Where the reference control's ground rows go (id, kind, source, lon, lat, "
              "h, sigma_e, sigma_n, sigma_h); their image rows go to --output with the tie "
              "points. Default with BLOCK.toml its points.ground; required with IMAGEs.")
@click.option("--reference-diagnostics", metavar="CSV", default=None,
              help="Also write every reference candidate: image, reference row/col, offset "
              "(warped image minus reference, reference pixels), correlation and status "
              "(kept, nodata, correlation, offset).")
@click.option("--min-overlap", type=click.FloatRange(0.0, 1.0), default=None,
              metavar="FRACTION",
              help="Match only pairs whose footprints on the DEM overlap by at least this share "
              "of the smaller one. Default the block file's match.min_overlap, else 0.1.")
@click.option("--max-pairs-per-image", type=click.IntRange(min=0), default=None, metavar="N",
              help="Match at most N pairs per image, the largest overlaps first (0: no cap); "
              "a spanning forest of the overlap graph is kept whatever N, so the cap never "
              "splits the block. Default the block file's match.max_pairs_per_image, else 10.")
@click.option("--min-convergence", "min_convergence", type=click.FloatRange(0.0, 180.0),
              default=None, metavar="DEG",
              help="Skip pairs whose lines of sight meet at less than DEG at their overlap's "
              "centre (for stereo; tie points need no convergence). Default 0.")
@click.option("--max-convergence", "max_convergence", type=click.FloatRange(0.0, 180.0),
              default=None, metavar="DEG",
              help="Skip pairs whose lines of sight meet at more than DEG (views too different "
              "to match). Default none.")
@click.option("--pairs-only", is_flag=True,
              help="Print the pair graph (images, candidate and selected pairs with their "
              "overlap and convergence, connected components, images with no pair) and stop "
              "before matching.")
@scheduler_opt
@click.option("--diagnostics", metavar="CSV", default=None,
              help="Also write every candidate match: positions, the models' prediction, "
              "offset, ratio, correlation, residuals across/along the epipolar direction and "
              "status (kept or the test that rejected it).")
@overwrite_opt
def match(inputs: tuple[str, ...], output: str, models: tuple[str, ...], ids: tuple[str, ...],
          dem_source: str | None, dem_vertical: str | None, geoid: str | None,
          dem_sigma: float | None, no_crop: bool, force: bool,
          search_px: float | None, max_keypoints: int, contrast_threshold: float, ratio: float,
          min_score: float, order: int, k_sigma: float, sigma_px: float | None,
          ictp_share: float, id_prefix: str, reference: str | None,
          reference_accuracy: float | None, reference_local_accuracy: float | None,
          reference_band: int | None,
          ground_output: str | None, reference_diagnostics: str | None,
          min_overlap: float | None, max_pairs_per_image: int | None,
          min_convergence: float | None, max_convergence: float | None, pairs_only: bool,
          scheduler: str, diagnostics: str | None, overwrite: bool) -> None:
    """Measure tie points between IMAGEs (or the images of BLOCK.toml) and write them as the
    image-measurement CSV 'geoblock adjust' reads: id, image, row, col, sigma, kind (tp).

    The pairs are chosen from the images' footprints on the DEM (their overlap, the
    convergence of their lines of sight, at most --max-pairs-per-image per image without
    splitting the block) and the pair graph is reported before any matching (--pairs-only
    stops there). The matching runs as tasks (one per image's keypoints, one per pair) on
    --scheduler: local threads, processes, or a dask.distributed cluster, with the same CSV,
    byte for byte, on every one. Each selected pair is matched: SIFT keypoints
    (OpenCV) spread over the overlap; each keypoint of the first image goes to the DEM
    through its model and into the second image through the other's (the prediction);
    descriptors are compared only with keypoints inside a window around the prediction
    (Lowe's ratio test). A first pass with wide windows finds the models' disagreement (a
    low-order image-space bias); the second pass searches narrow windows around the
    corrected predictions, elongated along the epipolar direction (where the DEM's height
    errors move the match). Matches are refined to sub-pixel accuracy by correlation and
    least-squares matching in the models' local geometry, then tested against the models:
    across the epipolar direction only noise is allowed (epipolar test), along it the
    height parallax (height test). A point matched in more than two images has one id.

    Rows and columns are in the pixels of each image's model: for an IMAGE that is a crop of
    the model's scene (a pixel-unit geotransform without CRS, as shareloc's crops carry), the
    scene's pixels, the ones the model file describes (--no-crop takes every IMAGE's pixels
    as its model's). With BLOCK.toml, each [[images]] entry
    needs 'raster' (the image file) besides 'model'; the DEM is the block's [dem].
    A summary line (keypoints, candidates, kept, rejections per test, matches per second)
    goes to standard error.

    With --reference (or a block file's [reference] table), every image is also matched
    against the reference orthoimage at the reference's resolution: ground control points
    whose ground comes from the reference (height from the DEM) and whose sigmas come from
    the reference's accuracy (--reference-accuracy, CE90 metres) and the DEM's (--dem-sigma);
    their ground rows go to --ground-output, their image rows (kind gcp) to --output with the
    tie points. One IMAGE is enough then (no tie points).

    \b
    Examples:
      geoblock match left.tif right.tif --model left.geom --model right.geom \\
          --dem N44E005.hgt --dem-vertical geoid -o tp.csv
      geoblock match teo/block.toml -o teo/points/tp.csv --diagnostics teo/match.csv
      geoblock match right.tif --model right.geom --dem N44E005.hgt --dem-vertical geoid \\
          --reference left_ortho.tif --reference-accuracy 8.5 -o image.csv \\
          --ground-output ground.csv
    """
    from pathlib import Path

    from geoblock.errors import MatchError
    from geoblock.match.pipeline import MatchOptions, match_images

    def say(message: str) -> None:
        click.echo(message, err=True)

    block_mode = len(inputs) == 1 and Path(inputs[0]).suffix.lower() == ".toml"
    spec = None
    if block_mode:
        for name, given in (("--model", models), ("--image-id", ids), ("--no-crop", no_crop),
                            ("--force", force)):
            if given:
                raise click.UsageError(f"{name} applies to IMAGEs, not to a block file (the "
                                       "block file names each image's model and raster)")
        from geoblock.io.blocks import read_block

        spec = read_block(inputs[0])
    ref = _reference(spec, inputs[0] if block_mode else None, reference, reference_accuracy,
                     reference_band, ground_output, reference_local_accuracy)
    if ref is not None:
        ground_output = ref["ground_output"]
    if reference_diagnostics is not None and ref is None:
        raise click.UsageError("--reference-diagnostics applies with --reference (or a block "
                               "file's [reference] table)")
    check_outputs({"--output": output, "--diagnostics": diagnostics,
                   "--ground-output": ground_output,
                   "--reference-diagnostics": reference_diagnostics},
                  {"IMAGE" if not block_mode else "BLOCK.toml": inputs, "--model": models,
                   "--dem": dem_source, "--reference": None if ref is None else ref["path"]},
                  overwrite=overwrite)
    options: dict[str, Any] = {
        "search_px": search_px, "max_keypoints": max_keypoints,
        "contrast_threshold": contrast_threshold, "ratio": ratio, "min_score": min_score,
        "order": order, "k": k_sigma, "sigma_px": sigma_px, "id_prefix": id_prefix,
        # the rejected candidates only for --diagnostics (a large block's memory)
        "keep_candidates": diagnostics is not None}
    if dem_sigma is not None:
        options["dem_sigma_m"] = dem_sigma
    pair_opts: dict[str, Any] = {
        "min_overlap": min_overlap, "min_convergence_deg": min_convergence,
        "max_convergence_deg": max_convergence,
        "max_pairs_per_image": None if max_pairs_per_image is None
        else (max_pairs_per_image or "none")}
    if spec is not None:
        if dem_sigma is None and spec.dem is not None and spec.dem.sigma is not None:
            options["dem_sigma_m"] = float(spec.dem.sigma)
        options.update(spec.match)  # the block's [match] table, under the options given
    options.update({k: (None if v == "none" else v) for k, v in pair_opts.items()
                    if v is not None})
    try:
        opts = MatchOptions(**options)
    except MatchError as exc:
        where = f"{inputs[0]}: [match]: " if block_mode else ""
        raise click.UsageError(f"{where}{exc}") from None
    if pairs_only:
        with using_scheduler(scheduler) as where:
            _print_pairs(spec, inputs, models, ids, no_crop, force, dem_source, dem_vertical,
                         geoid, opts, where)
        return
    if block_mode:
        assert spec is not None
        images = _block_images(spec, inputs[0])
        dem = open_dem_arg(dem_source, dem_vertical, geoid) if dem_source else \
            _block_dem(spec, inputs[0])
        with using_scheduler(scheduler) as where:
            result = match_images(images, dem, options=opts, progress=say, scheduler=where) \
                if len(spec.images) >= 2 or ref is None else None
    else:
        if len(inputs) < 2 and ref is None:
            raise click.UsageError("give two or more IMAGEs, or one BLOCK.toml (or one IMAGE "
                                   "with --reference)")
        if dem_source is None:
            raise click.UsageError("--dem DEM is required with IMAGEs (the terrain the models "
                                   "predict the matches through)")
        images = _images(inputs, models, ids, no_crop, force)
        dem = open_dem_arg(dem_source, dem_vertical, geoid)
        with using_scheduler(scheduler) as where:
            result = match_images(images, dem, options=opts, progress=say, scheduler=where) \
                if len(images) >= 2 else None
    control = None
    if ref is not None:
        from geoblock.match.reference import ReferenceOptions, match_reference

        sigma = dem_sigma if dem_sigma is not None else (
            spec.dem.sigma if spec is not None and spec.dem is not None
            and spec.dem.sigma is not None else opts.dem_sigma_m)
        assert dem is not None
        control = match_reference(images, ref["path"], dem,
                                  reference_accuracy_ce90_m=ref["accuracy"],
                                  dem_sigma_m=float(sigma),
                                  options=ReferenceOptions(
                                      band=ref["band"],
                                      local_accuracy_ce90_m=ref["local_accuracy"]),
                                  progress=say)
        if result is not None:
            import numpy as np

            common = np.intersect1d(result.id, control.ground["id"])
            if common.size:
                raise click.UsageError(f"tie-point ids {common[:3].tolist()} are also reference "
                                       "control ids: choose another --id-prefix")
    _write(result, output, diagnostics, ictp_share, control, ground_output,
           reference_diagnostics)
    if result is not None:
        say(result.summary())
    if control is not None:
        say(control.summary())


def _print_pairs(spec: Any, inputs: tuple[str, ...], models: tuple[str, ...],
                 ids: tuple[str, ...], no_crop: bool, force: bool, dem_source: str | None,
                 dem_vertical: str | None, geoid: str | None, opts: Any, where: Any) -> None:
    """``--pairs-only``: the pair graph on standard output."""
    from geoblock.match.pairs import select_pairs

    images: Any
    if spec is not None:  # the models are enough: no raster needed for the graph
        from geoblock.io.models import open_model

        images = {im.id: open_model(im.model) for im in spec.images}
        dem = open_dem_arg(dem_source, dem_vertical, geoid) if dem_source else \
            _block_dem(spec, inputs[0])
    else:
        if dem_source is None:
            raise click.UsageError("--dem DEM is required with IMAGEs (the terrain the "
                                   "footprints are placed on)")
        images = _images(inputs, models, ids, no_crop, force)
        dem = open_dem_arg(dem_source, dem_vertical, geoid)
    graph = select_pairs(images, dem, min_overlap=opts.min_overlap,
                         max_pairs_per_image=opts.max_pairs_per_image,
                         min_convergence_deg=opts.min_convergence_deg,
                         max_convergence_deg=opts.max_convergence_deg, scheduler=where)
    click.echo(graph.report(pairs=True))


def _images(paths: tuple[str, ...], models: tuple[str, ...], ids: tuple[str, ...],
            no_crop: bool, force: bool) -> list[MatchImage]:
    """The IMAGEs with their models (``--model`` in order, else the one stored in each)."""
    from pathlib import Path

    from geoblock.match.pipeline import MatchImage
    from geoblock.models.crop import CLI_NAMES

    if models and len(models) != len(paths):
        raise click.UsageError(f"give --model once per IMAGE ({len(paths)}), or not at all; "
                               f"got {len(models)}")
    if ids and len(ids) != len(paths):
        raise click.UsageError(f"give --image-id once per IMAGE ({len(paths)}), or not at all; got "
                               f"{len(ids)}")
    names = list(ids) if ids else [Path(p).stem for p in paths]
    out = []
    for k, path in enumerate(paths):
        model = models[k] if models else None
        out.append(MatchImage.from_files(names[k], path, model, crop=not no_crop, force=force,
                                         names=CLI_NAMES))
        image = out[-1]
        if image.offset != (0.0, 0.0):
            rows, cols = image.image.shape
            say = f"{image.name}: a {rows} x {cols} px crop at row/col {image.offset[0]:g}, " \
                  f"{image.offset[1]:g} of its model's scene; rows and columns are written " \
                  "in the scene's pixels"
            click.echo(say, err=True)
    return out


def _reference(spec: Any, block: str | None, path: str | None, accuracy: float | None,
               band: int | None, ground_output: str | None, local_accuracy: float | None = None
               ) -> dict[str, Any] | None:
    """The reference to match (the option's, else the block's), its accuracy, band and the
    ground output; None without a reference."""
    table = spec.reference if spec is not None else None
    if path is None and table is None:
        for name, given in (("--reference-accuracy", accuracy), ("--reference-band", band),
                            ("--reference-local-accuracy", local_accuracy),
                            ("--ground-output", ground_output)):
            if given is not None:
                raise click.UsageError(f"{name} applies with --reference (or a block file's "
                                       "[reference] table)")
        return None
    if path is None:
        assert table is not None
        path = str(table.path)
        if accuracy is None:
            accuracy = table.accuracy_ce90_m
        if band is None:
            band = table.band
    if local_accuracy is None and table is not None and table.local_accuracy_ce90_m is not None:
        local_accuracy = table.local_accuracy_ce90_m
    if local_accuracy is not None and not (math.isfinite(local_accuracy) and local_accuracy >= 0):
        raise click.BadParameter(f"must be a number >= 0 (metres), got {local_accuracy!r}",
                                 param_hint="--reference-local-accuracy")
    if accuracy is None:
        where = f" (or accuracy_ce90_m in the [reference] table of {block})" if block else ""
        raise click.UsageError(
            f"give the reference's absolute accuracy with --reference-accuracy CE90_M{where}: "
            "the adjustment weighs every control point by it, and geoblock does not guess it")
    if ground_output is None:
        if spec is None:
            raise click.UsageError("--ground-output CSV is required with --reference and "
                                   "IMAGEs (the control points' ground rows)")
        if spec.ground_points is None:
            raise click.UsageError(f"{block} names no points.ground: give --ground-output CSV "
                                   "for the reference control's ground rows")
        ground_output = str(spec.ground_points)
    return {"path": path, "accuracy": float(accuracy), "band": band or 1,
            "local_accuracy": float(local_accuracy or 0.0), "ground_output": ground_output}


def _block_dem(spec: Any, name: str) -> Any:
    if spec.dem is None:
        raise click.UsageError(f"{name}: no [dem] table, and no --dem: matching needs the "
                               "terrain")
    return spec.dem.to_source(name)


def _block_images(spec: Any, name: str) -> list[MatchImage]:
    from geoblock.errors import BlockFileError
    from geoblock.match.pipeline import MatchImage

    missing = [f"images[{k}] ({im.id})" for k, im in enumerate(spec.images) if im.raster is None]
    if missing:
        raise BlockFileError(f"{name}: {', '.join(missing)} name(s) no 'raster': geoblock "
                             "match needs each image's pixels (raster = \"image.tif\")")
    return [MatchImage.from_files(im.id, im.raster, im.model) for im in spec.images]


def _write(result: Any, output: str, diagnostics: str | None, ictp_share: float,
           control: Any = None, ground_output: str | None = None,
           reference_diagnostics: str | None = None) -> None:
    import numpy as np

    from geoblock.io.points import write_points

    columns = result.to_columns(ictp_share) if result is not None else None
    if control is not None:
        extra = control.measurements
        columns = extra if columns is None else {
            k: np.concatenate([np.asarray(columns[k]), np.asarray(extra[k])]) for k in columns}
        assert ground_output is not None
        write_points(ground_output, dict(control.ground))
    assert columns is not None
    write_points(output, columns)
    if diagnostics and result is not None:
        write_points(diagnostics, result.diagnostics())
    if reference_diagnostics and control is not None:
        write_points(reference_diagnostics, control.diagnostics())
