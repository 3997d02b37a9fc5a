"""`testbed evaluate`: the official KITTI evaluation of a result folder against a label folder."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .options import data_option, split_file, split_option


def _floats(ctx, param, value: str | None) -> list[float] | None:
    if value is None:
        return None
    try:
        return [float(v) for v in value.split(",") if v.strip()]
    except ValueError:
        raise click.BadParameter(f"'{value}' is not a comma-separated list of numbers") from None


@click.command()
@data_option("Dataset root whose training/label_2 holds the truth (or --gt).", required=False)
@click.option("--gt", "gt_dir", type=click.Path(exists=True, file_okay=False, path_type=Path),
              metavar="LABEL_DIR", help="A folder of label files with the truth, instead of --data.")
@click.option("--pred", "pred_dir", required=True,
              type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Result folder: one KITTI file with scores per frame; a missing file = no detections.")
@split_option(help="Frames of ImageSets/NAME.txt (of --data, or of ROOT when --gt is ROOT/training/"
                   "label_2); 'all' for every label file; a path (with a '/' or ending in .txt) to "
                   "such an ids file is read as it is.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False, path_type=Path),
              help="Write AP and breakdowns as JSON (key 'ap': {class: {metric: {R11, R40}}}).")
@click.option("--range-bins", "range_bins", callback=_floats,
              help="Distance bin edges in metres, e.g. 0,20,40,60,80 (ground x-z distance).")
@click.option("--classes", default="Car,Pedestrian,Cyclist", show_default=True,
              help="Comma-separated classes.")
@click.option("--match-iou", default=0.5, show_default=True, type=float,
              help="3D IoU above which a pair is matched for the error statistics.")
@click.option("--min-score", default=None, type=float,
              help="Detections below this score are left out of the error statistics (not of AP).")
@click.option("--max-distance", default=80.0, show_default=True, type=float,
              help="D of the volumetric location precision (the sensor's perceived range), metres.")
@click.option("--bootstrap", "draws", default=0, show_default=True, type=click.IntRange(min=0),
              help="Also give each AP|R40 its 95 % interval over this many draws of the frames "
                   "(with replacement; for small sets such as a few real frames).")
@click.option("--drives", "drives_path", type=click.Path(exists=True, path_type=Path),
              help="Which frames share a drive, for --bootstrap to draw whole drives: lines "
                   "'FRAME_ID DRIVE', or the KITTI devkit's mapping/ folder [default: every frame "
                   "its own].")
def evaluate(data: Path | None, gt_dir: Path | None, pred_dir: Path, split: str, json_out: Path | None,
             range_bins: list[float] | None, classes: str, match_iou: float, min_score: float | None,
             max_distance: float, draws: int, drives_path: Path | None) -> None:
    """Evaluate the result files in --pred against the truth of --data (or the label folder
    --gt): 2D, bird's-eye, 3D and AOS, AP|R11 and AP|R40, easy/moderate/hard, exactly as the
    KITTI devkit; plus AP per distance bin, matched-pair errors and the volumetric metrics.

    --pred and --gt are folders of label files, not dataset roots."""
    from kitti.drives import read_drives
    from kitti.eval import evaluate
    from kitti.eval.bootstrap import interval_table
    from kitti.eval.folders import load_folders
    from kitti.io import atomic_write_text

    if (data is None) == (gt_dir is None):
        raise click.UsageError("give the truth as --data ROOT or as --gt LABEL_DIR (one of them)")
    gt_dir = gt_dir or data / "training" / "label_2"
    ids = split_file(split, data or gt_dir.parent.parent)  # --gt: ROOT/training/label_2
    names = [c.strip() for c in classes.split(",") if c.strip()]
    try:
        drives = None if drives_path is None else read_drives(drives_path)
        gt, dt = load_folders(gt_dir, pred_dir, ids)
        res = evaluate(gt, dt, classes=names, range_bins=range_bins, progress=True,
                       match_iou=match_iou, min_score=min_score, max_distance=max_distance)
        doc = res.to_json()
        if draws:
            text, doc["bootstrap"] = interval_table(gt, dt, res, draws, drives)
    except ValueError as e:
        raise click.ClickException(str(e)) from None
    click.echo(res.table(), nl=False)
    if draws:
        click.echo("\n" + text, nl=False)
    if json_out:
        atomic_write_text(json_out, json.dumps(doc, indent=1) + "\n")
        click.echo(f"wrote {json_out}")
