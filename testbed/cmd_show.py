"""`testbed show`: one frame of any KITTI-format dataset as a picture."""

from __future__ import annotations

from pathlib import Path

import click

from .options import data_option


@click.command()
@data_option()
@click.option("--frame", "frame", required=True, help="Frame id, e.g. 000007 or 7.")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output PNG.")
@click.option("--pred", "pred", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Folder of KITTI result files to draw dashed over the truth.")
@click.option("--min-score", default=0.3, show_default=True, type=click.FloatRange(0, 1),
              help="Draw only predictions scoring at least this (result files keep a low-score tail).")
@click.option("--part", default="training", show_default=True, type=click.Choice(["training", "testing"]))
def show(data: Path, frame: str, out: Path, pred: Path | None, min_score: float, part: str) -> None:
    """Draw FRAME of the dataset at --data: the image with the labelled 3D boxes projected, and a
    bird's-eye view of the LiDAR points with the boxes, side by side."""
    from kitti.dataset import KittiDataset
    from kitti.errors import KittiFormatError
    from kitti.io import atomic_path

    from .draw import draw_frame, plt

    fid = frame.zfill(6)
    try:
        ds = KittiDataset(data, part)
    except KittiFormatError as e:
        raise click.ClickException(str(e)) from None
    if not ds.image_path(fid).exists():
        raise click.BadParameter(f"no image {ds.image_path(fid)}", param_hint="--frame")
    try:
        fig = draw_frame(ds, fid, pred, min_score=min_score)
    except (KittiFormatError, ValueError) as e:  # a label, calib or scan file, named
        raise click.ClickException(str(e)) from None
    except (OSError, SyntaxError) as e:  # a missing file names itself; a broken PNG does not
        raise click.ClickException(str(e) if getattr(e, "filename", None) else
                                   f"{ds.image_path(fid)}: cannot read the image: {e}") from None
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)
    click.echo(f"wrote {out}")
