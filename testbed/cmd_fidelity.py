"""`testbed fidelity`: how far one KITTI-format dataset ("sim") is from another ("real")."""

from __future__ import annotations

import os
from pathlib import Path

import click

_DATASET = click.Path(exists=True, file_okay=False, path_type=Path)


@click.command()
@click.option("--sim", "sim", required=True, type=_DATASET, help="Dataset root compared (KITTI layout).")
@click.option("--real", "real", required=True, type=_DATASET, help="Dataset root it is compared with.")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for report.md, fidelity.json and the plots.")
@click.option("--split", help="ImageSets/<NAME>.txt of both roots [default: every frame with an image].")
@click.option("--frames", type=click.IntRange(min=1), help="Only the first N ids of the split.")
@click.option("--tolerances", "tolerances", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Tolerance YAML [default: testbed/fidelity/tolerances.yaml].")
@click.option("--workers", type=click.IntRange(min=1), default=min(2, os.cpu_count() or 1),
              show_default=True, help="Worker processes (1: in this process).")
@click.option("--draws", type=click.IntRange(min=0), default=1000, show_default=True,
              help="Bootstrap draws of both sides' frames behind each verdict's 95 % interval (0: none).")
@click.option("--sim-drives", "sim_drives", type=click.Path(exists=True, path_type=Path),
              help="Which of SIM's frames share a drive, for the bootstrap to draw drives: lines "
                   "'FRAME_ID DRIVE', or the KITTI devkit's mapping/ folder; frames not named are a "
                   "drive each [default: every frame its own].")
@click.option("--real-drives", "real_drives", type=click.Path(exists=True, path_type=Path),
              help="The same for REAL.")
def fidelity(sim: Path, real: Path, out: Path, split: str | None, frames: int | None,
             tolerances: Path | None, workers: int, draws: int, sim_drives: Path | None,
             real_drives: Path | None) -> None:
    """Compare the LiDAR scans, images and labels of SIM with those of REAL: medians per
    statistic, relative differences with pass/fail verdicts, and overlaid histograms."""
    from kitti.drives import read_drives
    from kitti.errors import KittiFormatError

    from .backends import LocalBackend
    from .fidelity import compare, compute_stats, load_tolerances, write_report

    try:
        tol = load_tolerances(tolerances)
        drives = [None if p is None else read_drives(p) for p in (sim_drives, real_drives)]
        with LocalBackend(workers) as backend:
            sim_stats = compute_stats(sim, split, frames, backend)
            real_stats = compute_stats(real, split, frames, backend)
        comparison = compare(sim_stats, real_stats, tol, draws, *drives)
        write_report(comparison, out)
    except (KittiFormatError, ValueError) as e:
        raise click.ClickException(str(e)) from None
    counts = {v: sum(r.verdict == v for r in comparison.rows) for v in ("pass", "fail", "n/a")}
    undecided = sum(r.decided is False for r in comparison.rows)
    click.echo(f"{counts['pass']} pass, {counts['fail']} fail, {counts['n/a']} n/a"
               + (f" ({undecided} undecided by these frames)" if draws else "")
               + f"; wrote {out / 'report.md'}")
