"""``geoblock demo``: the whole pipeline on a simulated three-strip block, before and after."""

from __future__ import annotations

import click

from geoblock.cli.options import check_outputs, deprecated_aliases, overwrite_opt

__all__ = ["demo"]


@deprecated_aliases(force="--overwrite", size="--variant")
@click.command(short_help="The whole pipeline on a simulated block: adjust, orthorectify, "
               "mosaic, report.")
@click.argument("outdir", metavar="[OUTDIR]", default="geoblock-demo", required=False)
@click.option("--variant", "size", type=click.Choice(["small", "tiny"]), default="small",
              show_default=True,
              help="small: 600 x 600 px strips at 100 m (under half a minute on 2 cores); tiny: "
              "200 x 200 px strips at 300 m (a few seconds, for tests).")
@click.option("--seed", type=click.IntRange(min=0), default=None, metavar="N",
              help="Seed of every random draw (default: the preset's).")
@overwrite_opt
def demo(outdir: str, size: str, seed: int | None, overwrite: bool) -> None:
    """geoblock's whole pipeline on built-in data, before and after the block adjustment.

    Simulates a small block like Teo et al.'s (the teo2010-spot5 preset, small variant: three
    SPOT-5 strips with 10-15 % overlaps over 0-3800 m of terrain, a 40 m DEM, GCPs, ICPs, TPs
    and ICTPs, images rendered through the true models); adjusts it as 'geoblock adjust
    OUTDIR/block/block.toml' does (method dg), in single mode (each strip with its GCPs) and
    in block mode (GCPs, TPs and DEM elevation control); orthorectifies each strip on the
    measured DEM with its on-board model (before) and its block-adjusted model (after) and
    mosaics both sets; measures the errors at the GCPs and ICPs from the truth, the ICTP
    discrepancies and the misregistration of the orthos at each seam (matched on the
    images). Writes
    OUTDIR/report.md (before/after tables), OUTDIR/results.json, OUTDIR/quicklook.png (the
    two mosaics), OUTDIR/errors.png and OUTDIR/seams.png. Progress goes to standard error,
    stage by stage. OUTDIR defaults to ./geoblock-demo.

    A non-empty OUTDIR is refused before anything is done unless --overwrite. With it, a
    previous demo's output (marked by OUTDIR/.geoblock-demo) is replaced (block/,
    adjustment/, onboard/, orthos/, mosaic.tif, contribution.tif, report.md, results.json
    and the PNGs; other files are kept), and any other directory is written into (files of
    the same name are replaced; it is not marked as a demo output).

    \b
    Examples:
      geoblock demo
      geoblock demo /tmp/demo --variant tiny
      geoblock demo /tmp/demo --overwrite
    """
    from pathlib import Path

    from geoblock.workflows.demo import run_demo

    check_outputs({"OUTDIR": outdir}, overwrite=overwrite, directories=["OUTDIR"])
    result = run_demo(Path(outdir), size=size, seed=seed, force=overwrite,
                      progress=lambda m: click.echo(m, err=True))
    click.echo(f"report: {result.report}")
    click.echo(f"quicklook: {result.quicklook}")
