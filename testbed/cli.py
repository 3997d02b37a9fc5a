"""`testbed`: one command, one subcommand per stage of the pipeline."""

from __future__ import annotations

import click

from .cmd_show import show


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def cli() -> None:
    """Synthetic road scenes with exact 3D truth, a 2D detector, a 2D-to-3D lifter and the
    KITTI evaluation, swept over LiDAR beams, range and weather."""


cli.add_command(show)


def main() -> None:
    cli()
