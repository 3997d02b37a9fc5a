"""`testbed show`: one frame of any KITTI-format dataset as a picture."""

from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("dataset", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--frame", "frame", required=True, help="Frame id, e.g. 000007 or 7.")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output PNG.")
@click.option("--pred", "pred", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Folder of KITTI result files to draw dashed over the truth.")
@click.option("--min-score", default=0.3, show_default=True, type=click.FloatRange(0, 1),
              help="Draw only predictions scoring at least this (result files keep a low-score tail).")
@click.option("--part", default="training", show_default=True, type=click.Choice(["training", "testing"]))
def show(dataset: Path, frame: str, out: Path, pred: Path | None, min_score: float, part: str) -> None:
    """Draw FRAME of DATASET: the image with the labelled 3D boxes projected, and a bird's-eye
    view of the LiDAR points with the boxes, side by side."""
    from kitti.dataset import KittiDataset
    from kitti.io import atomic_path

    from .draw import draw_frame, plt

    fid = frame.zfill(6)
    ds = KittiDataset(dataset, part)
    if not ds.image_path(fid).exists():
        raise click.BadParameter(f"no image {ds.image_path(fid)}", param_hint="--frame")
    fig = draw_frame(ds, fid, pred, min_score=min_score)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)
    click.echo(f"wrote {out}")
