"""`testbed detect`: the FlexiNet 2D detector over a KITTI-format dataset -> KITTI result files."""

from __future__ import annotations

from pathlib import Path

import click

from .options import data_option, split_name, split_option


@click.command()
@data_option()
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for the result files (<id>.txt, one per frame, empty when nothing is found).")
@click.option("--weights", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Checkpoint [default: the shipped detector/weights/flexinet_small.pt].")
@split_option()
@click.option("--part", default="training", show_default=True, type=click.Choice(["training", "testing"]))
@click.option("--conf", default=0.01, show_default=True, type=click.FloatRange(0, 1),
              help="Lowest score written (AP needs the low-score tail).")
@click.option("--iou", default=0.6, show_default=True, type=click.FloatRange(0, 1), help="NMS IoU.")
@click.option("--batch", default=4, show_default=True, type=click.IntRange(1))
@click.option("--threads", default=2, show_default=True, type=click.IntRange(1),
              help="CPU threads (1 is faster on a machine already busy with other jobs).")
@click.option("--mirror/--no-mirror", default=True, show_default=True,
              help="Also read each image mirrored and merge both passes' boxes (twice the work).")
@click.option("--scales", default=None,
              help="Comma-separated input scales, the first 1: each image is also read letterboxed "
                   "into the network input scaled by each further factor [default: 1,1.25,0.83 for "
                   "the shipped weights (detector.infer.DEFAULT_SCALES), 1 for others; 1 alone takes "
                   "a quarter of the shipped read's time].")
@click.option("--fuse-boxes/--best-boxes", default=False, show_default=True,
              help="Each kept box's sides: the score-weighted mean of its views' best boxes, or its "
                   "best view's alone (scores and the boxes kept are the same either way; a read "
                   "of one view, --no-mirror --scales 1, has nothing to fuse).")
def detect(data: Path, out: Path, weights: Path | None, split: str, part: str, conf: float, iou: float,
           batch: int, threads: int, mirror: bool, scales: str | None, fuse_boxes: bool) -> None:
    """Detect Car, Pedestrian and Cyclist in every frame of the --split of --data; boxes are
    mapped back from the letterboxed input to exact image pixels; 3D fields are the format's
    placeholders."""
    import torch

    from detector.infer import detect_dataset, parse_scales
    from kitti.errors import KittiFormatError

    torch.set_num_threads(threads)
    try:
        factors = None if scales is None else parse_scales(scales)
    except ValueError as e:
        raise click.BadParameter(str(e), param_hint="--scales") from None
    try:
        res = detect_dataset(data, out, weights, split_name(split), part, batch, conf, iou,
                             mirror=mirror, scales=factors, fuse_boxes=fuse_boxes)
    except (KittiFormatError, ValueError, FileNotFoundError) as e:
        raise click.ClickException(str(e)) from None
    click.echo(f"{sum(len(v) for v in res.values())} detections in {len(res)} frames written to {out}")
