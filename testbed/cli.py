"""`testbed`: one command, one subcommand per stage of the pipeline.

Each subcommand is a thin adapter in its own `cmd_*` module (parse options, call one library
function, print). The group imports a module only when its command is asked for, and the modules
import their stage's heavy dependencies (torch, Embree, pyrender) only when the stage runs, so
`testbed --help` is instant and `testbed reduce-beams` on real KITTI never loads the simulator.
"""

from __future__ import annotations

import importlib

import click

COMMANDS = {  # name -> module defining a click command of the same name (dashes as underscores)
    "generate": "cmd_generate", "rescan": "cmd_rescan", "relabel": "cmd_relabel",
    "reduce-beams": "cmd_reduce_beams",
    "detect": "cmd_detect", "train-detector": "cmd_train_detector", "lift": "cmd_lift",
    "train-lifter": "cmd_train_lifter", "evaluate": "cmd_evaluate", "run": "cmd_run",
    "sweep": "cmd_sweep", "show": "cmd_show", "fidelity": "cmd_fidelity",
}


class LazyGroup(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        module = importlib.import_module(f"testbed.{COMMANDS[name]}")
        return getattr(module, name.replace("-", "_"))


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
def cli() -> None:
    """Synthetic road scenes with exact 3D truth, a 2D detector, a 2D-to-3D lifter and the
    KITTI evaluation, swept over LiDAR beams, range and weather."""


def main() -> None:
    cli()
