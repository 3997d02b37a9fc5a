"""`testbed fidelity`: how far one KITTI-format dataset ("sim") is from another ("real")."""

from __future__ import annotations

from pathlib import Path

import click

from .options import DATASET, data_option, split_name, split_option, workers_option


@click.command()
@data_option("Dataset root compared, e.g. generated frames (--sim: its former spelling).", "--sim")
@click.option("--real", "real", required=True, type=DATASET, metavar="ROOT",
              help="Dataset root it is compared with.")
@click.option("--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for report.md, fidelity.json and the plots.")
@split_option(help="Frames of ImageSets/NAME.txt of both roots; 'all' for every frame with an image.")
@click.option("--frames", type=click.IntRange(min=1), help="Only the first N ids of the split.")
@click.option("--tolerances", "tolerances", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Tolerance YAML [default: fidelity/tolerances.yaml].")
@workers_option()
@click.option("--draws", type=click.IntRange(min=0), default=1000, show_default=True,
              help="Bootstrap draws of both sides' frames behind each verdict's 95 % interval (0: none).")
@click.option("--sim-drives", "sim_drives", type=click.Path(exists=True, path_type=Path),
              help="Which of the --data frames share a drive, for the bootstrap to draw drives: lines "
                   "'FRAME_ID DRIVE', or the KITTI devkit's mapping/ folder; frames not named are a "
                   "drive each [default: every frame its own].")
@click.option("--real-drives", "real_drives", type=click.Path(exists=True, path_type=Path),
              help="The same for --real.")
@click.option("--skip-unreadable", is_flag=True,
              help="Leave out a frame whose files cannot be read (each is named here and in "
                   "report.md) [default: such a frame stops the command].")
def fidelity(data: Path, real: Path, out: Path, split: str, frames: int | None,
             tolerances: Path | None, workers: int, draws: int, sim_drives: Path | None,
             real_drives: Path | None, skip_unreadable: bool) -> None:
    """Compare the LiDAR scans, images and labels of the dataset at --data with those of --real:
    medians per statistic, relative differences with pass/fail verdicts, and overlaid
    histograms."""
    from kitti.drives import read_drives
    from kitti.errors import KittiFormatError

    from .backends import LocalBackend
    from fidelity import UnreadableFrame, compare, compute_stats, load_tolerances, write_report

    unreadable = "skip" if skip_unreadable else "raise"
    try:
        tol = load_tolerances(tolerances)
        drives = [None if p is None else read_drives(p) for p in (sim_drives, real_drives)]
        with LocalBackend(workers) as backend:
            sides = [compute_stats(root, split_name(split), frames, backend, unreadable)
                     for root in (data, real)]
        for name, stats in zip(("sim", "real"), sides):
            for fid, err in stats.skipped:
                click.echo(f"skipped {name} frame {fid}: {err}", err=True)
        comparison = compare(*sides, tol, draws, *drives)
        write_report(comparison, out)
    except UnreadableFrame as e:
        raise click.ClickException(f"{e} (--skip-unreadable leaves such frames out)") from None
    except (KittiFormatError, ValueError) as e:
        raise click.ClickException(str(e)) from None
    counts = {v: sum(r.verdict == v for r in comparison.rows) for v in ("pass", "fail", "n/a")}
    undecided = sum(r.decided is False for r in comparison.rows)
    click.echo(f"{counts['pass']} pass, {counts['fail']} fail, {counts['n/a']} n/a"
               + (f" ({undecided} undecided by these frames)" if draws else "")
               + f"; wrote {out / 'report.md'}")
