"""`testbed`: one command, one subcommand per stage of the pipeline.

Each subcommand is a thin adapter in its own `cmd_*` module (parse options, call one library
function, print). The group imports a module only when its command is asked for, and the modules
import their stage's heavy dependencies (torch, Embree, pyrender) only when the stage runs, so
`testbed --help` is instant and `testbed reduce-beams` on real KITTI never loads the simulator.

One grammar (testbed/options.py): a command that reads a dataset takes it as `--data ROOT`;
`--split NAME` is ImageSets/NAME.txt, `all` (the default) every frame; `--workers` has one
default. The commands are listed in the order of the work.
"""

from __future__ import annotations

import importlib
import sys

import click

DISTRIBUTION = "kitti-testbed"

COMMANDS = {  # name -> module defining a click command of the same name (dashes as underscores),
    # in the order of the work: make a dataset and look at it, derive others from it, read it,
    # score the reading, all of it at once, against real data, and the networks' training
    "generate": "cmd_generate", "show": "cmd_show",
    "rescan": "cmd_rescan", "reduce-beams": "cmd_reduce_beams", "relabel": "cmd_relabel",
    "detect": "cmd_detect", "lift": "cmd_lift", "evaluate": "cmd_evaluate",
    "run": "cmd_run", "sweep": "cmd_sweep", "fidelity": "cmd_fidelity",
    "train-detector": "cmd_train_detector", "train-lifter": "cmd_train_lifter",
}


def _close_progress_bars() -> None:
    """Close the progress bars an error left open, so that the error starts a line of its own."""
    tqdm = sys.modules.get("tqdm")
    for bar in list(getattr(getattr(tqdm, "tqdm", None), "_instances", ())):
        bar.close()


class LazyGroup(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        module = importlib.import_module(f"testbed.{COMMANDS[name]}")
        return getattr(module, name.replace("-", "_"))

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except Exception:
            _close_progress_bars()
            raise


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name=DISTRIBUTION, prog_name="testbed", message="%(prog)s %(version)s")
def cli() -> None:
    """Synthetic road scenes with exact 3D truth, a 2D detector, a 2D-to-3D lifter and the
    KITTI evaluation, swept over LiDAR beams, range and weather.

    A command that reads a dataset takes it as --data ROOT (a KITTI-format root); --split NAME
    reads ROOT/ImageSets/NAME.txt, 'all' (the default) every frame."""


def main() -> None:
    cli()
