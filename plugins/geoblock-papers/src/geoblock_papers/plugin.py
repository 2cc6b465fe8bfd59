"""geoblock hooks of the papers' experiments: the ``geoblock experiment`` command.

Kept cheap to import: the command's module is imported when the CLI is built, the experiments
themselves (numpy, the block engine, the plugins' fits) when one runs.
"""

from __future__ import annotations

from typing import Any

import geoblock


@geoblock.hookimpl
def geoblock_register_commands(cli: Any) -> None:
    """``geoblock experiment`` (:mod:`geoblock_papers.cli`)."""
    from geoblock_papers.cli import experiment

    cli.add_command(experiment)
