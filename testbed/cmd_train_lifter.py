"""`testbed train-lifter`: train the size and orientation network on a KITTI-format dataset."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .options import data_option, split_name, split_option


@click.command("train-lifter")
@data_option()
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Run folder: last.pt, best.pt, log.jsonl, summary.json.")
@click.option("--epochs", default=30, show_default=True, type=click.IntRange(min=1))
@click.option("--crop-size", default=224, show_default=True, type=click.IntRange(min=32),
              help="Crop side in pixels (000: 224; 96 trains fast on a CPU).")
@click.option("--width", default=0.5, show_default=True, type=click.FloatRange(min=0.1),
              help="MobileNetV2 width multiplier.")
@click.option("--batch-size", default=64, show_default=True, type=click.IntRange(min=2))
@click.option("--lr", default=2e-3, show_default=True, type=float)
@click.option("--seed", default=0, show_default=True, type=int)
@click.option("--threads", default=2, show_default=True, type=click.IntRange(min=1))
@split_option("--train-split", "train", "Training frames: ImageSets/NAME.txt; 'all' (or a split file "
              "that is absent) for every frame.")
@split_option("--val-split", "val", "Validation frames: ImageSets/NAME.txt; 'all' (or absent): every 10th "
              "training frame is held out.")
@click.option("--all-frames", is_flag=True, help="The same as --train-split all --val-split all.")
@click.option("--resume", is_flag=True, help="Continue from OUT/last.pt.")
@click.option("--init", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Start from these weights (fine-tuning, e.g. on new data).")
def train_lifter(data: Path, out: Path, epochs: int, crop_size: int, width: float, batch_size: int,
                 lr: float, seed: int, threads: int, train_split: str, val_split: str, all_frames: bool,
                 resume: bool, init: Path | None) -> None:
    """Train the lifter's MobileNetV2-style size and MultiBin orientation network."""
    from kitti.errors import KittiFormatError
    from lifter.train import train

    try:
        summary = train(data, out, epochs=epochs, crop_size=crop_size, width=width,
                        batch_size=batch_size, lr=lr, seed=seed, threads=threads, resume=resume, init=init,
                        train_split=None if all_frames else split_name(train_split),
                        val_split=None if all_frames else split_name(val_split))
    except (KittiFormatError, ValueError) as e:
        raise click.ClickException(str(e)) from None
    click.echo(json.dumps(summary["last"]))
    click.echo(f"best checkpoint: {out / 'best.pt'}")
