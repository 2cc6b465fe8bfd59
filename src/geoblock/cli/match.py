"""``geoblock match``: tie points between images, guided by their sensor models and a DEM."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click

from geoblock.cli.options import (
    check_outputs,
    dem_options,
    force_opt,
    deprecated_aliases,
    no_crop_opt,
    open_dem_arg,
    output_opt,
    overwrite_opt,
    positive_float,
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
          ictp_share: float, id_prefix: str, diagnostics: str | None, overwrite: bool) -> None:
    """Measure tie points between IMAGEs (or the images of BLOCK.toml) and write them as the
    image-measurement CSV 'geoblock adjust' reads: id, image, row, col, sigma, kind (tp).

    Every overlapping pair (the models' footprints on the DEM) is matched: SIFT keypoints
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

    \b
    Examples:
      geoblock match left.tif right.tif --model left.geom --model right.geom \\
          --dem N44E005.hgt --dem-vertical geoid -o tp.csv
      geoblock match teo/block.toml -o teo/points/tp.csv --diagnostics teo/match.csv
    """
    from pathlib import Path

    from geoblock.match.pipeline import MatchOptions, match_block, match_images

    def say(message: str) -> None:
        click.echo(message, err=True)

    block_mode = len(inputs) == 1 and Path(inputs[0]).suffix.lower() == ".toml"
    check_outputs({"--output": output, "--diagnostics": diagnostics},
                  {"IMAGE" if not block_mode else "BLOCK.toml": inputs, "--model": models,
                   "--dem": dem_source}, overwrite=overwrite)
    options: dict[str, Any] = {
        "search_px": search_px, "max_keypoints": max_keypoints,
        "contrast_threshold": contrast_threshold, "ratio": ratio, "min_score": min_score,
        "order": order, "k": k_sigma, "sigma_px": sigma_px, "id_prefix": id_prefix}
    if dem_sigma is not None:
        options["dem_sigma_m"] = dem_sigma
    opts = MatchOptions(**options)
    if block_mode:
        for name, given in (("--model", models), ("--image-id", ids), ("--no-crop", no_crop),
                            ("--force", force)):
            if given:
                raise click.UsageError(f"{name} applies to IMAGEs, not to a block file (the "
                                       "block file names each image's model and raster)")
        dem = open_dem_arg(dem_source, dem_vertical, geoid) if dem_source else None
        result = match_block(inputs[0], dem=dem, options=opts, progress=say)
    else:
        if len(inputs) < 2:
            raise click.UsageError("give two or more IMAGEs, or one BLOCK.toml")
        if dem_source is None:
            raise click.UsageError("--dem DEM is required with IMAGEs (the terrain the models "
                                   "predict the matches through)")
        images = _images(inputs, models, ids, no_crop, force)
        result = match_images(images, open_dem_arg(dem_source, dem_vertical, geoid),
                              options=opts, progress=say)
    _write(result, output, diagnostics, ictp_share)
    say(result.summary())


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


def _write(result: Any, output: str, diagnostics: str | None, ictp_share: float) -> None:
    from geoblock.io.points import write_points

    write_points(output, result.to_columns(ictp_share))
    if diagnostics:
        write_points(diagnostics, result.diagnostics())
