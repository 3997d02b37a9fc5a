"""`testbed rescan`: the same worlds, another LiDAR; images and labels stay byte-identical."""

from __future__ import annotations

from pathlib import Path

import click

from .options import data_option, lidar_option, workers_option


@click.command()
@data_option("Dataset root written by `testbed generate` (its worlds are rebuilt from meta/).")
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="New dataset root; an interrupted run resumes here.")
@lidar_option(required=True)
@click.option("--beams", type=click.IntRange(min=1),
              help="Beams: on a real preset every k-th laser (N must divide its count); "
                   "on 'uniform' any N spread over +2..-24.9 deg.")
@click.option("--max-range", type=click.FloatRange(min=0, min_open=True),
              help="Hard range cut-off, m [default: the preset's].")
@click.option("--fog-extinction", type=click.FloatRange(min=0),
              help="LiDAR-only weather: fog extinction beta (1/m) instead of the world's.")
@click.option("--rain-rate", type=click.FloatRange(min=0),
              help="LiDAR-only weather: rain rate (mm/h) instead of the world's.")
@workers_option()
def rescan(data: Path, out: Path, lidar_preset: str, beams: int | None,
           max_range: float | None, fog_extinction: float | None, rain_rate: float | None,
           workers: int) -> None:
    """Rebuild every frame's world of the dataset at --data from meta/ and scan it again into --out.

    --fog-extinction / --rain-rate change the weather the LiDAR sees (a sensor study: images and
    labels stay those of the world's own weather)."""
    from simgen.rescan import RescanRequest, WeatherOverride
    from simgen.rescan import rescan as rescan_dataset
    from simgen.spec import LidarSection

    from .backends import LocalBackend

    weather = (WeatherOverride(fog_extinction, rain_rate)
               if fog_extinction is not None or rain_rate is not None else None)
    request = RescanRequest(LidarSection(preset=lidar_preset, beams=beams, max_range=max_range),
                            weather)
    try:
        with LocalBackend(workers) as backend:
            ids = rescan_dataset(data, out, request, backend)
    except ValueError as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{len(ids)} frames rescanned with {lidar_preset} in {out}")
