"""``geoblock adjust``: the DEM-aided block adjustment of a block file (MBA, DG, RFM, RPCV-0/1)."""

from __future__ import annotations

import click

from geoblock.cli.options import check_outputs, deprecated_aliases, overwrite_opt

__all__ = ["adjust"]


@deprecated_aliases(out="--output")
@click.command(short_help="Adjust a block of images (MBA, DG, RFM, RPCV-0/1) with GCPs, TPs, DEM.")
@click.argument("block_file", metavar="BLOCK.toml", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out_dir", metavar="DIR", default=None,
              help="Output directory (default: the block file's outputs.directory, else "
              "'adjusted' beside it). An existing non-empty one is refused unless "
              "--overwrite, and then replaced as a whole only when it holds nothing but a "
              "previous adjustment's output; left untouched when the adjustment fails.")
@click.option("--mode", type=click.Choice(["block", "single"]), default=None,
              help="block: all images with GCPs, TPs and DEM; single: each image alone with "
              "its GCPs. Default: the block file's (block).")
@click.option("--compare-single", is_flag=True, default=False,
              help="Also run the single adjustment and put both side by side in the report.")
@click.option("--dem-control", type=click.Choice(["observation", "iterate", "none"]),
              default=None, help="DEM elevation control of the TPs (default observation).")
@click.option("--robust", type=click.Choice(["none", "huber", "cauchy", "snooping"]),
              default=None, help="Robust estimation of the image measurements (default none).")
@click.option("--collocation/--no-collocation", default=None,
              help="Least-squares collocation of the residual vectors after the adjustment "
              "(default: on for the dg method).")
@click.option("--max-iterations", type=click.IntRange(min=1), default=None,
              help="Iteration cap of Gauss-Newton (default 30).")
@click.option("--components", type=click.Choice(["refuse", "separate", "joint"]),
              default=None, help="A block whose images form groups that no GCP or tie point "
              "links: refuse (default; the groups are named before solving), separate (each "
              "group adjusted alone, one report) or joint (one system).")
@click.option("--solver", type=click.Choice(["auto", "dense", "direct", "iterative"]),
              default=None, help="How the reduced normal equations are solved: dense "
              "Cholesky, sparse direct factorisation, or preconditioned conjugate gradients; "
              "auto (default) chooses by size and memory and the report says which.")
@click.option("--start", "start", metavar="DIR_OR_FILE", default=None,
              type=click.Path(exists=True),
              help="Warm start from a previous 'geoblock adjust' output (its directory or its "
              "report.json): the images and points it solved start from its solution, the "
              "others from their on-board models; the same answer in fewer iterations.")
@click.option("--no-figures", is_flag=True, default=False, help="Do not draw the PNG figures.")
@overwrite_opt
def adjust(block_file: str, out_dir: str | None, mode: str | None, compare_single: bool,
           dem_control: str | None, robust: str | None, collocation: bool | None,
           max_iterations: int | None, components: str | None, solver: str | None,
           start: str | None, no_figures: bool, overwrite: bool) -> None:
    """Adjust the block described by BLOCK.toml and write the adjusted models and a report.

    The block file names the images (sensor-model files), the parameter set or image-space
    correction of each (or a method that chooses them: mba, dg, rfm, rpcv0, rpcv1), the point
    files (ground.csv: id, lon, lat, h, sigma_e, sigma_n, sigma_h, kind gcp|icp|hcp[, source,
    sigma_shift_e, sigma_shift_n, sigma_shift_h]; image.csv: id, image, row, col, sigma[, kind
    gcp|icp|tp|ictp|hcp]), the DEM with its accuracy and the engine's options (docs:
    user-guide/block-adjustment.md). Command-line options override the file's.

    Writes DIR/models/<image>.json (each opens with geoblock.open_model and orthorectifies
    with 'geoblock ortho'), DIR/report.json (per-measurement residuals, redundancy numbers,
    test statistics and blunder flags, per-point ground coordinates and covariances,
    statistics, sigma0, iteration log), DIR/report.md (the papers' tables: GCP/ICP RMSE E/N
    per image and per source, ICTP relative accuracy per overlap, single versus block; the
    common error estimated for each control source; HCP residuals; CE90/CE95/LE90
    predicted from the posterior beside the empirical figures at the ICPs) and error-vector
    plots as PNG. One progress line per iteration goes to standard error.

    \b
    Examples:
      geoblock simulate teo2010-spot5 teo && geoblock adjust teo/block.toml -o teo/adj
      geoblock adjust block.toml --robust cauchy --compare-single
    """
    from pathlib import Path

    from geoblock.adjust.block import adjust as run
    from geoblock.io.blocks import open_block, read_block
    from geoblock.report.adjustment import check_output_directory, write_result

    spec = read_block(block_file)
    out: str | Path
    if out_dir is None:
        out = spec.outputs.get("directory") or Path(block_file).resolve().parent / "adjusted"
    else:
        out = out_dir
    check_outputs({"--output": out}, {"BLOCK.toml": block_file}, overwrite=overwrite,
                  directories=["--output"])
    check_output_directory(out)  # replaced as a whole: only a previous output may be there
    opened = open_block(spec, name=block_file)
    options = dict(opened.options)
    for key, value in (("mode", mode), ("dem_control", dem_control), ("robust", robust),
                       ("collocation", collocation), ("max_iterations", max_iterations),
                       ("components", components), ("solver", solver)):
        if value is not None:
            options[key] = value

    def say(message: str) -> None:
        click.echo(message, err=True)

    if start is not None:
        options["start"] = start
    result = run(opened.block, progress=say, **options)
    single = None
    if compare_single and options.get("mode", "block") == "block":
        single = run(opened.block, progress=say,
                     **{**options, "mode": "single", "start": None})
    title = f"Block adjustment: {opened.spec.name or Path(block_file).name} " \
            f"(method {opened.spec.method})"
    written = write_result(result, out, single=single, title=title, figures=not no_figures)
    click.echo(result.report_text())
    if single is not None:
        click.echo("single adjustment, for comparison:")
        click.echo(single.report_text())
    click.echo(f"wrote {len(written)} files to {out}")
