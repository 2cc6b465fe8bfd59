"""``geoblock simulate``: simulate a block from a named preset or a scenario TOML file."""

from __future__ import annotations

from pathlib import Path

import click

from geoblock.cli.options import check_outputs, deprecated_aliases, overwrite_opt

__all__ = ["simulate"]


def _presets_text() -> str:
    from geoblock.simulate.large import LARGE_PRESETS
    from geoblock.simulate.presets import PRESETS

    lines = [f"  {name}: {text}" for name, text in PRESETS.items()]
    lines += [f"  {name}: {spec.images} images, {spec.tps} TPs, points only (no images, "
              "no report; --images, --tps)" for name, spec in LARGE_PRESETS.items()]
    return "\n".join(lines)


def _list_presets(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    click.echo("Scenario presets (variants: small, full):")
    click.echo(_presets_text())
    ctx.exit()


class _PresetsHelp(click.Command):
    """Fills the ``{presets}`` slot of the help text when help is shown (the presets module
    is not imported by ``geoblock --help`` or by other commands)."""

    def get_help(self, ctx: click.Context) -> str:
        if self.help and "{presets}" in self.help:
            self.help = self.help.replace("{presets}", "\n    ".join(_presets_text().splitlines()))
        return super().get_help(ctx)


@deprecated_aliases(force="--overwrite")
@click.command(cls=_PresetsHelp,
               short_help="Simulate a block with known truth (preset or scenario TOML).")
@click.argument("scenario", metavar="SCENARIO")
@click.argument("outdir", metavar="OUTDIR")
@click.option("--variant", type=click.Choice(["small", "full"]), default=None,
              help="Variant of a preset: small (seconds) or full (the papers' image sizes, "
              "minutes). Default: small.")
@click.option("--seed", type=click.IntRange(min=0), default=None, metavar="N",
              help="Seed of every random draw (default: the scenario's).")
@click.option("--onboard-errors", type=click.Choice(["realistic", "bias-drift"]), default=None,
              help="The on-board error model of every image: realistic (biases and drifts "
              "plus the attitude wander, look-angle and orbital-period ephemeris errors "
              "measured on real products) or bias-drift (biases and linear drifts only, "
              "as before issue 27). Default: the scenario's (realistic).")
@click.option("--no-images", is_flag=True, default=False,
              help="Do not render the raw images (models, DEMs and points only).")
@click.option("--images", "n_images", type=click.IntRange(min=4), default=None, metavar="N",
              help="Large points-only presets (continental-spot-1000, -10000): about N images "
              "instead (strips and scenes scaled alike).")
@click.option("--tps", type=click.IntRange(min=0), default=None, metavar="N",
              help="Large points-only presets: N tie points in the whole block.")
@overwrite_opt
@click.option("--list", "list_presets", is_flag=True, is_eager=True, expose_value=False,
              callback=_list_presets, help="List the scenario presets and exit.")
def simulate(scenario: str, outdir: str, variant: str | None, seed: int | None,
             onboard_errors: str | None, no_images: bool, n_images: int | None,
             tps: int | None, overwrite: bool) -> None:
    """Simulate the block SCENARIO into OUTDIR: a preset name or a scenario TOML file.

    Writes the true terrain and the measured DEM(s) (GeoTIFF), per image the true and the
    on-board model (JSON) and the raw image rendered through the true model, the point files
    (GCPs, ICPs, TPs, ICTPs) with their truth, block.toml for the adjustment engine, and
    report/ (footprints, accuracy of the on-board models at GCPs and ICPs, ICTP
    discrepancies; Markdown, CSV, PNG). A non-empty OUTDIR is refused unless --overwrite
    (then files of the same name are replaced, others kept). OUTDIR/scenario.toml is the scenario fully resolved:
    'geoblock simulate OUTDIR/scenario.toml OUT2' makes the same files again.

    \b
    Presets (--list):
    {presets}

    \b
    Examples:
      geoblock simulate teo2010-spot5 teo
      geoblock simulate aguilar2007-quickbird qb --variant full --no-images
      geoblock simulate my-block.toml out --seed 7 --overwrite
      geoblock simulate teo2010-spot5 teo-bd --onboard-errors bias-drift
      geoblock simulate continental-spot-1000 big --tps 200000

    The large presets (continental-spot-1000, continental-spot-10000) are points
    only: OUTDIR gets block.toml, the on-board models, the true terrain and the
    DEM, and the point files with their truth (geoblock.simulate.large).
    """
    from geoblock.simulate.large import LARGE_PRESETS

    check_outputs({"OUTDIR": outdir}, {"SCENARIO": scenario}, overwrite=overwrite,
                  directories=["OUTDIR"])
    if scenario in LARGE_PRESETS:
        _large(scenario, outdir, variant, seed, onboard_errors, n_images, tps)
        return
    if n_images is not None or tps is not None:
        raise click.UsageError("--images and --tps apply to the large presets "
                               f"({', '.join(LARGE_PRESETS)})")
    from geoblock.simulate.scenario import load_scenario
    from geoblock.workflows.scenario import run_scenario

    sc = load_scenario(scenario, variant=variant, seed=seed, onboard_errors=onboard_errors)
    path = Path(outdir)
    click.echo(f"{sc.name}: {sc.description}", err=True)
    result = run_scenario(sc, path, progress=lambda m: click.echo(m, err=True),
                          render=False if no_images else None)
    for note in result.notes:
        click.echo(f"Note: {note}", err=True)
    click.echo(f"{result.files['report']}")



def _large(name: str, outdir: str, variant: str | None, seed: int | None,
           onboard_errors: str | None, n_images: int | None, tps: int | None) -> None:
    """A points-only large preset into OUTDIR."""
    import time

    from geoblock.simulate.large import large_block, large_preset

    if variant is not None:
        raise click.UsageError(f"--variant does not apply to {name} (points only; --images "
                               "and --tps size it)")
    spec = large_preset(name, images=n_images, tps=tps, seed=seed)
    if onboard_errors is not None:
        spec = spec.replace(sensor=spec.sensor.replace(onboard_errors=onboard_errors))
    click.echo(f"{spec.name}: {spec.description}", err=True)
    t0 = time.perf_counter()
    block = large_block(spec, progress=lambda m: click.echo(m, err=True))
    files = block.write(Path(outdir), progress=lambda m: click.echo(m, err=True))
    click.echo(f"done in {time.perf_counter() - t0:.1f} s", err=True)
    click.echo(f"{files['block']}")
