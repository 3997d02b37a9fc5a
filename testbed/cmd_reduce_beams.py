"""`testbed reduce-beams`: fewer LiDAR rings by keeping every k-th one (thesis 000)."""

from __future__ import annotations

from pathlib import Path

import click

from .options import data_option, workers_option


@click.command("reduce-beams")
@data_option("Source dataset root (ours or real KITTI).")
@click.option("--beams", required=True, type=click.IntRange(min=1),
              help="Beams to keep; must divide the source's beam count.")
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="New dataset root; an interrupted run resumes here.")
@click.option("--source-beams", type=click.IntRange(min=1),
              help="Beams of the source scans [default: from meta/, else 64 (KITTI)].")
@workers_option()
def reduce_beams(data: Path, beams: int, out: Path, source_beams: int | None,
                 workers: int) -> None:
    """Keep rings 0, k, 2k, ... of every scan: rings from velodyne_info/ where present, else
    recovered from the KITTI point order (azimuth wraps) or elevation clustering."""
    from kitti.reduce import reduce_beams as reduce_dataset

    from .backends import LocalBackend

    try:
        with LocalBackend(workers) as backend:
            ids = reduce_dataset(data, out, beams, source_beams, backend)
    except ValueError as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{len(ids)} scans reduced to {beams} beams in {out}")
