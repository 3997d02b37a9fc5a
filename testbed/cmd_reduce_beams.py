"""`testbed reduce-beams`: fewer LiDAR rings by keeping every k-th one (thesis 000)."""

from __future__ import annotations

import os
from pathlib import Path

import click


@click.command("reduce-beams")
@click.option("--data", "dataset", required=True,
              type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Source dataset root (ours or real KITTI).")
@click.option("--beams", required=True, type=click.IntRange(min=1),
              help="Beams to keep; must divide the source's beam count.")
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="New dataset root; an interrupted run resumes here.")
@click.option("--source-beams", type=click.IntRange(min=1),
              help="Beams of the source scans [default: from meta/, else 64 (KITTI)].")
@click.option("--workers", type=click.IntRange(min=1), default=min(2, os.cpu_count() or 1),
              show_default=True, help="Worker processes (1: in this process).")
def reduce_beams(dataset: Path, beams: int, out: Path, source_beams: int | None,
                 workers: int) -> None:
    """Keep rings 0, k, 2k, ... of every scan: rings from velodyne_info/ where present, else
    recovered from the KITTI point order (azimuth wraps) or elevation clustering."""
    from kitti.reduce import reduce_beams as reduce_dataset

    from .backends import LocalBackend
    from .stages import sensor_beams

    try:
        with LocalBackend(workers) as backend:
            ids = reduce_dataset(dataset, out, beams, source_beams, backend,
                                 sensor_beams=sensor_beams(dataset))
    except ValueError as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{len(ids)} scans reduced to {beams} beams in {out}")
