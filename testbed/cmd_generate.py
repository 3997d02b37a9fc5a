"""`testbed generate`: a KITTI-format dataset from a scene spec (simgen.generate)."""

from __future__ import annotations

from pathlib import Path

import click

from .options import lidar_option, workers_option


@click.command()
@click.argument("spec_path", metavar="SPEC", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Dataset root (KITTI layout); an interrupted run resumes here.")
@click.option("--frames", type=click.IntRange(min=1), help="Number of frames [default: the spec's].")
@click.option("--seed", type=click.IntRange(min=0), help="Seed [default: the spec's].")
@workers_option("Worker processes (1: render in this process); the same output bytes whatever N.")
@lidar_option(none=True, help="overrides the spec's lidar:")
@click.option("--beams", type=click.IntRange(min=1), help="Beams of the --lidar preset.")
@click.option("--max-range", type=click.FloatRange(min=0, min_open=True), help="Max range of the --lidar preset, m.")
def generate(spec_path: Path, out: Path, frames: int | None, seed: int | None, workers: int,
             lidar_preset: str | None, beams: int | None, max_range: float | None) -> None:
    """Render, label and write the frames of SPEC (scenes/*.yaml) under --out.

    SPEC is a scene spec, not a dataset; the dataset written under --out is what the other
    commands read with --data ROOT."""
    from simgen.generate import generate as write_dataset
    from simgen.spec import LidarSection, SpecError, load_spec

    from .backends import LocalBackend

    try:
        spec = load_spec(spec_path)
    except SpecError as e:
        raise click.ClickException(str(e)) from None
    if lidar_preset is None and (beams is not None or max_range is not None):
        if spec.lidar is None:
            raise click.BadParameter("--beams/--max-range need a LiDAR (--lidar or the spec's lidar:)")
        lidar_preset = spec.lidar.preset
    if lidar_preset is not None and lidar_preset.lower() != "none":
        spec = spec.model_copy(update={"lidar": LidarSection(preset=lidar_preset, beams=beams,
                                                             max_range=max_range)})
    elif lidar_preset is not None:
        spec = spec.model_copy(update={"lidar": None})
    try:
        with LocalBackend(workers) as backend:
            ids = write_dataset(spec, out, frames=frames, seed=seed, backend=backend)
    except (ValueError, RuntimeError) as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{len(ids)} frames in {out}")
