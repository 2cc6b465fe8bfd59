"""``geoblock experiment``: run one of the papers' experiments and write its report."""

from __future__ import annotations

import click

from geoblock.cli.options import check_outputs, deprecated_aliases, overwrite_opt
from geoblock_papers.registry import EXPERIMENTS, all_variants

__all__ = ["experiment"]


def _names_help() -> str:
    lines = []
    for name, entry in EXPERIMENTS.items():
        lines.append(f"  {name:<12} {entry.summary}")
        if entry.runtime:
            times = ", ".join(f"{variant} {t}" for variant, t in entry.runtime.items())
            lines.append(f"  {'':<12} run time on 2 cores: {times}")
        for variant, note in entry.more_variants.items():
            lines.append(f"  {'':<12} --variant {variant}: {note}")
    return "\n".join(lines)


_HELP = """\
Reproduce the experiments of one of the four papers on simulated blocks.

NAME is one of:

\b
{names}

Each repetition simulates the paper's set-up (the `geoblock simulate` presets) with a new
seed, runs the paper's methods and compares with the simulated truth. OUTDIR (default
./experiment-NAME) receives report.md, which puts our figures beside the paper's, table by
table, with 95 % confidence intervals over the seeds and says which findings reproduced
(and why not), the PNG figures, and results.json with every number.

The small variant (the default) shrinks the images, not the set-up, and runs in CI;
--variant full uses the papers' image sizes and more seeds. A non-empty OUTDIR is refused
before anything is run unless --overwrite (then files of the same name are replaced).

\b
Examples:
  geoblock experiment teo2010
  geoblock experiment teo2010 out/teo-case2 --variant case2
  geoblock experiment chen2008 out/chen2008 --repeats 6 --seed 100
  geoblock experiment aguilar2007 /tmp/aguilar --variant full --repeats 20
"""


@deprecated_aliases(full=("--variant", "full"))
@click.command(help=_HELP.format(names=_names_help()),
               short_help="Reproduce a paper's experiments on simulated blocks, with a report.")
@click.argument("name", type=click.Choice(list(EXPERIMENTS)), metavar="NAME")
@click.argument("outdir", metavar="[OUTDIR]", required=False, default=None)
@click.option("--variant", type=click.Choice(list(all_variants())), default="small",
              show_default=True,
              help="small: shrunk images, the papers' set-up (seconds to a minute, the one CI "
              "runs); full: the papers' image sizes and more repetitions (minutes to hours); "
              "some experiments have more (listed under NAME above).")
@click.option("--repeats", type=click.IntRange(min=1), default=None, metavar="N",
              help="Repetitions over seeds (default: the experiment's, for the variant).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, metavar="N",
              help="First seed; repetition k uses seed + k.")
@overwrite_opt
def experiment(name: str, outdir: str | None, variant: str, repeats: int | None,
               seed: int, overwrite: bool) -> None:
    from pathlib import Path

    from geoblock_papers.registry import run_experiment

    if variant not in EXPERIMENTS[name].variants:
        raise click.BadParameter(f"experiment {name} has no variant {variant!r}; its "
                                 f"variants: {', '.join(EXPERIMENTS[name].variants)}",
                                 param_hint="'--variant'")
    path = Path(outdir) if outdir else Path(f"experiment-{name}")
    check_outputs({"OUTDIR": path}, overwrite=overwrite, directories=["OUTDIR"])
    result = run_experiment(name, path, variant=variant, repeats=repeats, seed=seed,
                            progress=lambda m: click.echo(m, err=True))
    click.echo(f"report: {result.report}")
    click.echo(f"results: {result.results}")

