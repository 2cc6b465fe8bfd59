"""``geoblock demo``: simulate, orthorectify and mosaic a three-strip block, and report."""

from __future__ import annotations

import click

__all__ = ["demo"]


@click.command(short_help="Simulate three SPOT-5 strips, orthorectify, mosaic and report.")
@click.argument("outdir", metavar="[OUTDIR]", default="geoblock-demo", required=False)
@click.option("--size", type=click.Choice(["small", "tiny"]), default="small",
              show_default=True,
              help="small: 600 x 600 px strips at 100 m (about half a minute); tiny: 200 x 200 "
              "px strips (a few seconds, for tests).")
@click.option("--seed", type=click.IntRange(min=0), default=None, metavar="N",
              help="Seed of every random draw (default: the preset's).")
@click.option("--force", is_flag=True, default=False,
              help="Write into a non-empty OUTDIR that is not a previous demo's output (files "
              "of the same name are replaced; the directory is not marked as a demo output).")
def demo(outdir: str, size: str, seed: int | None, force: bool) -> None:
    """geoblock's main job on built-in data: simulate, orthorectify, mosaic, report.

    Simulates a small block like Teo et al.'s (the teo2010-spot5 preset, small variant: three
    SPOT-5 strips with 10-15 % overlaps over 0-3800 m of terrain, a 40 m DEM, GCPs, ICPs, TPs
    and ICTPs), orthorectifies each raw image with its ON-BOARD model (what a user is given)
    on the measured DEM, mosaics the orthos and writes OUTDIR/report.md (footprints, the
    on-board models' accuracy at the check points, ICTP discrepancies between strips) and
    OUTDIR/quicklook.png (the mosaic with the strips' outlines). OUTDIR defaults to
    ./geoblock-demo.

    Re-running is safe: the demo writes a marker file, OUTDIR/.geoblock-demo, and a later
    demo into a directory holding it replaces the previous demo's outputs (block/, orthos/,
    mosaic.tif, contribution.tif, report.md, quicklook.png; other files are kept). A
    non-empty OUTDIR without the marker is refused (exit code 2) unless --force.

    \b
    Examples:
      geoblock demo
      geoblock demo /tmp/demo --force
    """
    from pathlib import Path

    from geoblock.errors import DemoOutdirError
    from geoblock.workflows.demo import run_demo

    path = Path(outdir)
    try:
        result = run_demo(path, size=size, seed=seed, force=force,
                          progress=lambda m: click.echo(m, err=True))
    except DemoOutdirError as exc:  # raised before anything is written
        hint = "" if exc.path.exists() and not exc.path.is_dir() else (
            "; or pass --force to write into it (files of the same name are replaced)")
        raise click.UsageError(f"{exc}{hint}") from None
    click.echo(f"report: {result.report}")
    click.echo(f"quicklook: {result.quicklook}")
