"""`testbed relabel`: the same frames under other label rules; only labels and meta change."""

from __future__ import annotations

from pathlib import Path

import click

from .options import data_option, workers_option


@click.command()
@data_option("Dataset root written by `testbed generate` (its rules and worlds are read from meta/).")
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="New dataset root; an interrupted run resumes here.")
@click.option("--min-height-px", type=float, help="2D box height below which a row is DontCare.")
@click.option("--max-distance", type=float, help="Distance (m, x-z plane) beyond which a row is DontCare.")
@click.option("--min-visible-share", type=float, help="Visible share below which a row is DontCare.")
@click.option("--min-lidar-points", type=int,
              help="LiDAR returns on an object below which its row is DontCare (0: no such rule).")
@click.option("--silhouette-sides", help="Comma-separated classes whose 2D box sides come from "
                                         "the silhouette ('' for none).")
@workers_option()
def relabel(data: Path, out: Path, min_height_px: float | None, max_distance: float | None,
            min_visible_share: float | None, min_lidar_points: int | None,
            silhouette_sides: str | None, workers: int) -> None:
    """Label every frame of the dataset at --data (written by `testbed generate`) again into --out.

    Rules not given stay those the dataset was generated with. Images, scans and everything else
    are linked, unchanged; with the same rules the labels and meta come out byte for byte."""
    from pydantic import ValidationError

    from simgen.relabel import relabel as relabel_dataset
    from simgen.relabel import source_rules
    from simgen.spec import LabelRules

    from .backends import LocalBackend

    asked = {"min_height_px": min_height_px, "max_distance": max_distance,
             "min_visible_share": min_visible_share, "min_lidar_points": min_lidar_points,
             "silhouette_sides": (None if silhouette_sides is None else
                                  tuple(c.strip() for c in silhouette_sides.split(",") if c.strip()))}
    try:
        rules = source_rules(data).model_dump()
        rules.update({k: v for k, v in asked.items() if v is not None})
        rules = LabelRules.model_validate(rules)
        with LocalBackend(workers) as backend:
            ids = relabel_dataset(data, out, rules, backend)
    except ValidationError as e:
        raise click.ClickException("; ".join(_option_error(err) for err in e.errors())) from None
    except ValueError as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{len(ids)} frames relabelled in {out}")


def _option_error(err: dict) -> str:
    """A LabelRules validation error named by its option (and item, for a list)."""
    field, *item = err["loc"]
    where = f" (item {int(item[0]) + 1})" if item else ""
    return f"--{str(field).replace('_', '-')}{where}: {err['msg']}"
