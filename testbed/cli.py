"""`testbed`: one command, one subcommand per stage of the pipeline."""

from __future__ import annotations

import click

from .cmd_evaluate import evaluate
from .cmd_detect import detect
from .cmd_train_detector import train_detector
from .cmd_generate import generate
from .cmd_lift import lift
from .cmd_train_lifter import train_lifter
from .cmd_show import show
from .cmd_rescan import rescan
from .cmd_reduce_beams import reduce_beams
from .cmd_run import run
from .cmd_sweep import sweep


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def cli() -> None:
    """Synthetic road scenes with exact 3D truth, a 2D detector, a 2D-to-3D lifter and the
    KITTI evaluation, swept over LiDAR beams, range and weather."""


cli.add_command(evaluate)
cli.add_command(detect)
cli.add_command(train_detector)
cli.add_command(generate)
cli.add_command(lift)
cli.add_command(train_lifter)
cli.add_command(show)
cli.add_command(rescan)
cli.add_command(reduce_beams)
cli.add_command(run)
cli.add_command(sweep)


def main() -> None:
    cli()
