"""The options every `testbed` command spells the same way.

- the dataset a command reads: `--data ROOT` (a KITTI-format root: ROOT/training/image_2, ...);
- `--split NAME`: the frames of ROOT/ImageSets/NAME.txt, `all` for every frame, `all` by default;
- `--workers N`: processes for the per-frame jobs, one default everywhere (the output bytes do
  not depend on it: results come back in job order, `testbed.backends`);
- `--lidar PRESET`: the presets listed in the help.

Importing this module loads click only (`testbed --help` imports every command module).
"""

from __future__ import annotations

import os
from pathlib import Path

import click

DATASET = click.Path(exists=True, file_okay=False, path_type=Path)

ALL = "all"
DEFAULT_SPLIT = ALL  # lift's, evaluate's and fidelity's default already, and the split every root has
DEFAULT_WORKERS = min(2, os.cpu_count() or 1)  # the 2-core machines this runs on

# simgen.lidar.PRESETS, spelled out here: importing simgen loads the simulator (tests/testbed/
# test_cli.py checks that the two agree).
LIDAR_PRESETS = ("hdl64e", "hdl32e", "vlp32c", "vlp16", "uniform")
LIDAR_HELP = f"LiDAR preset: {', '.join(LIDAR_PRESETS[:-1])} or {LIDAR_PRESETS[-1]}"


def data_option(help: str = "KITTI-format dataset root (ours or real KITTI).", *aliases: str, **kw):
    """`--data ROOT` (and any `aliases`), the dataset a command reads; required unless told
    otherwise."""
    kw.setdefault("required", True)
    return click.option("--data", *aliases, "data", type=DATASET, metavar="ROOT", help=help, **kw)


def split_option(name: str = "--split", default: str = DEFAULT_SPLIT,
                 help: str = "Frames of ImageSets/NAME.txt of the dataset; 'all' for every frame."):
    return click.option(name, default=default, show_default=True, metavar="NAME", help=help)


def split_name(value: str) -> str | None:
    """A --split value as the library functions take it: None for every frame."""
    return None if value == ALL else value


def split_file(value: str, root: Path) -> Path | None:
    """The ids file of a --split value: None for 'all'; ROOT/ImageSets/NAME.txt for a NAME; a value
    with a '/' or ending in .txt is taken as the path of such a file."""
    if value == ALL:
        return None
    named = "/" not in value and not value.endswith(".txt")
    path = root / "ImageSets" / f"{value}.txt" if named else Path(value)
    if not path.is_file():
        raise click.BadParameter(f"no split file {path}", param_hint="--split")
    return path


def workers_option(help: str = "Worker processes (1: in this process); the same output bytes whatever N."):
    return click.option("--workers", type=click.IntRange(min=1), default=DEFAULT_WORKERS,
                        show_default=True, metavar="N", help=help)


def lidar_option(required: bool = False, none: bool = False, help: str = ""):
    """`--lidar PRESET`, its presets listed; `none: True` also takes 'none' (no LiDAR)."""
    text = LIDAR_HELP + (", or 'none' for none" if none else "") + (f"; {help}." if help else ".")
    return click.option("--lidar", "lidar_preset", required=required, metavar="PRESET", help=text)


def stack(*decorators):
    """Several option decorators as one (listed in the help in the order given)."""
    def apply(fn):
        for decorate in reversed(decorators):
            fn = decorate(fn)
        return fn
    return apply


backend_options = [
    workers_option("Parallel jobs (processes for the local backend, CPUs for a local Ray); the same "
                   "output bytes whatever N."),
    click.option("--backend", default="local", show_default=True, type=click.Choice(["local", "ray"])),
    click.option("--address", default=None, help="Ray cluster address (default: a local Ray instance)."),
]


with_backend_options = stack(*backend_options)  # how `run` and `sweep` execute their jobs
