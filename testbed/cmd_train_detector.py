"""`testbed train-detector`: train FlexiNet on a KITTI-format dataset (ours or real KITTI)."""

from __future__ import annotations

from pathlib import Path

import click


def _split(value: str) -> str | None:
    return None if value == "all" else value


@click.command("train-detector")
@click.option("--data", required=True, multiple=True,
              type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="KITTI-format training root; repeat to train on several (their frames in order).")
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Run folder: last.pt (each epoch), weights.pt (final EMA weights), history.csv/png.")
@click.option("--preset", default="small", show_default=True, type=click.Choice(["small", "s", "vehicle"]),
              help="depth/width multiples: small 0.33/0.25, s 0.33/0.50, vehicle 0.55/0.55.")
@click.option("--epochs", default=30, show_default=True, type=click.IntRange(1))
@click.option("--img-size", nargs=2, type=click.IntRange(32), default=None,
              help="Network input W H (multiples of 32) [default: 640 wide, height to fit].")
@click.option("--batch", default=16, show_default=True, type=click.IntRange(1))
@click.option("--lr", default=0.01, show_default=True, type=float)
@click.option("--momentum", default=0.94, show_default=True, type=float)
@click.option("--weight-decay", default=5e-4, show_default=True, type=float)
@click.option("--schedule", default="cosine", show_default=True, type=click.Choice(["cosine", "step"]))
@click.option("--warmup-epochs", default=1.0, show_default=True, type=float)
@click.option("--activation", default="hardswish", show_default=True,
              type=click.Choice(["hardswish", "silu", "swish", "mish", "frelu"]))
@click.option("--box-loss", default="diou", show_default=True, type=click.Choice(["diou", "giou", "ciou"]))
@click.option("--mosaic", default=1.0, show_default=True, type=click.FloatRange(0, 1), help="Mosaic probability.")
@click.option("--scale", default=0.4, show_default=True, type=click.FloatRange(0, 0.99), help="Zoom +- range.")
@click.option("--fliplr", default=0.5, show_default=True, type=click.FloatRange(0, 1))
@click.option("--hsv/--no-hsv", default=True, show_default=True, help="Colour jitter.")
@click.option("--photometric/--no-photometric", default=True, show_default=True,
              help="Sim-to-real photometric set: white balance, contrast, gamma, greyscale, blur, sensor noise, "
                   "JPEG, cut-out (detector/augment.py).")
@click.option("--wb-gain", default=0.1, show_default=True, type=click.FloatRange(0, 1, max_open=True),
              help="Per-channel white-balance gain drawn from 1 +- this.")
@click.option("--blur-sigma", nargs=2, default=(0.3, 1.5), show_default=True, type=click.FloatRange(0),
              help="Gaussian blur sigma range LOW HIGH, in pixels of a 1242-wide KITTI frame.")
@click.option("--noise-prob", default=0.5, show_default=True, type=click.FloatRange(0, 1),
              help="Probability of Poisson-Gaussian sensor noise.")
@click.option("--noise-full-well", nargs=2, default=(3000.0, 20000.0), show_default=True,
              type=click.FloatRange(1), help="Full-well range LOW HIGH (electrons at white); lower is noisier.")
@click.option("--jpeg-prob", default=0.2, show_default=True, type=click.FloatRange(0, 1),
              help="Probability of a JPEG re-encode (quality 50-95).")
@click.option("--cutout-prob", default=0.25, show_default=True, type=click.FloatRange(0, 1),
              help="Probability of 1-3 grey/noise rectangles (no box covered more than half).")
@click.option("--randconv-prob", default=0.0, show_default=True, type=click.FloatRange(0, 1),
              help="Probability of RandConv-mix texture randomisation (a random convolution, its size "
                   "drawn from --randconv-kernel, mixed with the image; detector/augment.py).")
@click.option("--randconv-kernel", "randconv_kernels", multiple=True, type=click.IntRange(1),
              default=(1, 3, 5, 7), show_default=True,
              help="RandConv kernel sizes drawn uniformly (odd; repeat the option: --randconv-kernel 1 "
                   "--randconv-kernel 3).")
@click.option("--randconv-keep-below", default=0.0, show_default=True, type=click.FloatRange(0),
              help="Boxes lower than this (pixels of a 1242-wide KITTI frame) keep their own pixels under "
                   "a random convolution, as do as many same-sized decoy patches (detector/augment.py); "
                   "0: the whole image is convolved.")
@click.option("--randconv-consistency", default=0.0, show_default=True, type=click.FloatRange(0),
              help="Weight of RandConv's consistency term; > 0 builds each batch of --batch images from "
                   "--batch/2 samples, each seen without and with a random convolution, and adds this "
                   "times a divergence of their objectness (--randconv-consistency-target; "
                   "detector/loss.py). Needs --randconv-prob 0.")
@click.option("--randconv-consistency-target", default="mutual", show_default=True,
              type=click.Choice(["mutual", "plain"]),
              help="mutual: Jensen-Shannon divergence, both views learn from it; plain: KL from the plain "
                   "view's objectness, held fixed, to the convolved view's.")
@click.option("--mixup", default="none", show_default=True, type=click.Choice(["none", "mixup", "thresholded"]),
              help="004 Mixup: plain, or only when the two images' boxes overlap below --mixup-iou.")
@click.option("--mixup-prob", default=0.5, show_default=True, type=click.FloatRange(0, 1))
@click.option("--mixup-iou", default=0.4, show_default=True, type=click.FloatRange(0, 1))
@click.option("--close-mosaic", default=3, show_default=True, type=click.IntRange(0),
              help="Last epochs without mosaic/zoom/Mixup (plain letterboxed images; flips, HSV and "
                   "the photometric set stay as set).")
@click.option("--train-split", default="train", show_default=True, help="ImageSets name, or 'all'.")
@click.option("--val-data", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Evaluation root [default: the first --data].")
@click.option("--val-split", default="val", show_default=True, help="ImageSets name, or 'all'.")
@click.option("--eval-every", default=1, show_default=True, type=click.IntRange(0),
              help="Epochs between 2D AP evaluations (0: never).")
@click.option("--init", "init_weights", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Start from these weights (fine-tuning, e.g. real KITTI from synthetic); keeps their anchors.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0))
@click.option("--threads", default=2, show_default=True, type=click.IntRange(1))
@click.option("--resume", is_flag=True, help="Continue from OUT/last.pt.")
def train_detector(data: tuple[Path, ...], out: Path, preset: str, epochs: int, img_size, batch: int, lr: float,
                   momentum: float, weight_decay: float, schedule: str, warmup_epochs: float,
                   activation: str, box_loss: str, mosaic: float, scale: float, fliplr: float, hsv: bool,
                   photometric: bool, wb_gain: float, blur_sigma: tuple[float, float], noise_prob: float,
                   noise_full_well: tuple[float, float], jpeg_prob: float, cutout_prob: float,
                   randconv_prob: float, randconv_kernels: tuple[int, ...], randconv_keep_below: float,
                   randconv_consistency: float,
                   randconv_consistency_target: str, mixup: str,
                   mixup_prob: float, mixup_iou: float, close_mosaic: int, train_split: str,
                   val_data: Path | None, val_split: str, eval_every: int, init_weights: Path | None,
                   seed: int, threads: int, resume: bool) -> None:
    """Train the FlexiNet 2D detector (Car incl. Van, Pedestrian, Cyclist) on DATA (one or more
    roots; the split applies to each)."""
    from detector.augment import AugmentConfig
    from detector.train import TrainConfig, train
    from kitti.errors import KittiFormatError

    try:
        aug = AugmentConfig(mosaic=mosaic, scale=scale, fliplr=fliplr,
                            hsv=AugmentConfig().hsv if hsv else (0.0, 0.0, 0.0),
                            photometric=photometric, gain=wb_gain, blur_sigma=tuple(blur_sigma),
                            noise_prob=noise_prob, noise_full_well=tuple(noise_full_well),
                            jpeg_prob=jpeg_prob, cutout_prob=cutout_prob, randconv_prob=randconv_prob,
                            randconv_kernels=tuple(randconv_kernels), randconv_keep_below=randconv_keep_below,
                            mixup=mixup, mixup_prob=mixup_prob, mixup_iou=mixup_iou)
        cfg = TrainConfig(data=tuple(str(d) for d in data), out=str(out), preset=preset, epochs=epochs,
                          img_size=tuple(img_size) if img_size else None, batch=batch, lr=lr,
                          momentum=momentum, weight_decay=weight_decay, warmup_epochs=warmup_epochs,
                          schedule=schedule, activation=activation, box_loss=box_loss, augment=aug,
                          randconv_consistency=randconv_consistency,
                          randconv_consistency_target=randconv_consistency_target,
                          close_mosaic=close_mosaic, train_split=_split(train_split),
                          val_split=_split(val_split), val_data=str(val_data) if val_data else None,
                          eval_every=eval_every, init=str(init_weights) if init_weights else None,
                          seed=seed, threads=threads)
        row = train(cfg, resume=resume)
    except (KittiFormatError, ValueError, FileNotFoundError) as e:
        raise click.ClickException(str(e)) from None
    click.echo(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))
    click.echo(f"weights: {out / 'weights.pt'}")
