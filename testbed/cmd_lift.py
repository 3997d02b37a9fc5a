"""`testbed lift`: 2D boxes -> 3D boxes (KITTI result files) by one of the lifter's methods."""

from __future__ import annotations

from pathlib import Path

import click

from lifter.methods import METHODS

from .options import data_option, split_name, split_option


@click.command()
@data_option()
@click.option("--boxes", required=True,
              help="'gt' (the label_2 boxes of the road users, oracle) or a folder of "
                   "detection result files (testbed detect).")
@click.option("--method", required=True, type=click.Choice(list(METHODS)),
              help="; ".join(f"{m.name}: {m.summary}" for m in METHODS.values()))
@split_option()
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for the result files (<id>.txt).")
@click.option("--priors", type=click.Choice(["net", "truth"]), default="net", show_default=True,
              help="Size and orientation from the network, or from the labels (ablation; --boxes gt).")
@click.option("--weights", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Size/orientation checkpoint [default: the shipped lifter/weights].")
@click.option("--mirror/--no-mirror", default=True, show_default=True,
              help="The network reads each crop and its mirror image (twice its work).")
@click.option("--side-sd", type=click.FloatRange(min=0.0), metavar="PX",
              help="How far the detections' left and right box sides lie from the true boxes': "
                   "the sd of their errors, or with --side-dof the Student-t's scale (pixels; "
                   "benchmarks/detector_sides.py measures both), which `fit` then weighs them by; "
                   "0: as a label's [default: the shipped detector's, "
                   "lifter.pipeline.SHIPPED_SIDE_ERRORS].")
@click.option("--side-dof", type=click.FloatRange(min=0.0, min_open=True), metavar="NU",
              help="The detections' side errors are Student-t with NU degrees of freedom (heavy "
                   "tails: a side far off pulls the box less); needs --side-sd [default: Gaussian].")
def lift(data: Path, boxes: str, method: str, split: str, out: Path, priors: str,
         weights: Path | None, mirror: bool, side_sd: float | None, side_dof: float | None) -> None:
    """Lift the 2D boxes of every frame of the --split of --data to 3D with METHOD."""
    from kitti.errors import KittiFormatError
    from lifter.pipeline import lift_dataset

    try:
        detections = None if boxes == "gt" else Path(boxes)
        if detections is None and (side_sd is not None or side_dof is not None):
            raise click.UsageError("--side-sd and --side-dof describe detected boxes: they need "
                                   "--boxes FOLDER")
        if side_dof is not None and side_sd is None:
            raise click.UsageError("--side-dof needs --side-sd, the Student-t's scale")
        n = lift_dataset(data, detections, method, out, split_name(split), priors=priors, weights=weights,
                         mirror=mirror, side_sd=side_sd, side_dof=side_dof)
    except (KittiFormatError, ValueError, FileNotFoundError) as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{n} 3D boxes written to {out}")
