"""``geoblock experiment``: run one of the papers' experiments and write its report."""

from __future__ import annotations

import click

from geoblock_papers.registry import EXPERIMENTS

__all__ = ["experiment"]


def _names_help() -> str:
    lines = []
    for name, entry in EXPERIMENTS.items():
        lines.append(f"  {name:<12} {entry.summary}")
        if entry.runtime:
            times = ", ".join(f"{variant} {t}" for variant, t in entry.runtime.items())
            lines.append(f"  {'':<12} run time on 2 cores: {times}")
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

The small variant (the default) shrinks the images, not the set-up, and runs in CI; --full
uses the papers' image sizes and more seeds.

\b
Examples:
  geoblock experiment teo2010
  geoblock experiment chen2008 out/chen2008 --repeats 6 --seed 100
  geoblock experiment aguilar2007 /tmp/aguilar --full --repeats 20
"""


@click.command(help=_HELP.format(names=_names_help()),
               short_help="Reproduce a paper's experiments on simulated blocks, with a report.")
@click.argument("name", type=click.Choice(list(EXPERIMENTS)), metavar="NAME")
@click.argument("outdir", metavar="[OUTDIR]", required=False, default=None)
@click.option("--full", is_flag=True, default=False,
              help="The papers' image sizes and more repetitions (minutes to hours) instead of "
              "the small variant (seconds to a minute, the one CI runs).")
@click.option("--repeats", type=click.IntRange(min=1), default=None, metavar="N",
              help="Repetitions over seeds (default: the experiment's, for the variant).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True, metavar="N",
              help="First seed; repetition k uses seed + k.")
def experiment(name: str, outdir: str | None, full: bool, repeats: int | None,
               seed: int) -> None:
    from pathlib import Path

    from geoblock_papers.registry import run_experiment

    path = Path(outdir) if outdir else Path(f"experiment-{name}")
    result = run_experiment(name, path, full=full, repeats=repeats, seed=seed,
                            progress=lambda m: click.echo(m, err=True))
    click.echo(f"report: {result.report}")
    click.echo(f"results: {result.results}")

