"""`testbed train-detector`: train FlexiNet on a KITTI-format dataset (ours or real KITTI)."""

from __future__ import annotations

from functools import partial
from pathlib import Path

import click

from .options import DATASET, data_option, split_option, stack

opt = partial(click.option, show_default=True)  # every default in the help
P = click.FloatRange(0, 1)  # a probability


@click.command("train-detector")
@data_option("KITTI-format training root; repeat for several (their frames in order).", multiple=True)
@click.option("--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Run folder: last.pt (each epoch), weights.pt (final EMA weights), history.csv/png.")
@opt("--preset", default="small", type=click.Choice(["small", "s", "vehicle"]),
     help="depth/width multiples: small 0.33/0.25, s 0.33/0.50, vehicle 0.55/0.55.")
@opt("--epochs", default=30, type=click.IntRange(1))
@click.option("--img-size", nargs=2, type=click.IntRange(32), default=None,
              help="Network input W H (multiples of 32) [default: 640 wide, height to fit].")
@stack(opt("--batch", default=16, type=click.IntRange(1)), opt("--lr", default=0.01, type=float),
       opt("--momentum", default=0.94, type=float), opt("--weight-decay", default=5e-4, type=float))
@stack(opt("--schedule", default="cosine", type=click.Choice(["cosine", "step"])),
       opt("--warmup-epochs", default=1.0, type=float))
@opt("--activation", default="hardswish", type=click.Choice(["hardswish", "silu", "swish", "mish", "frelu"]))
@opt("--box-loss", default="diou", type=click.Choice(["diou", "giou", "ciou"]))
@stack(opt("--mosaic", default=1.0, type=P, help="Mosaic probability."), opt("--fliplr", default=0.5, type=P),
       opt("--scale", default=0.4, type=click.FloatRange(0, 0.99), help="Zoom +- range."))
@opt("--hsv/--no-hsv", default=True, help="Colour jitter.")
@opt("--photometric/--no-photometric", default=True,
     help="Sim-to-real photometric set: white balance, contrast, gamma, greyscale, blur, sensor noise, "
          "JPEG, cut-out (detector/augment.py).")
@opt("--wb-gain", default=0.1, type=click.FloatRange(0, 1, max_open=True),
     help="Per-channel white-balance gain drawn from 1 +- this.")
@opt("--blur-sigma", nargs=2, default=(0.3, 1.5), type=click.FloatRange(0),
     help="Gaussian blur sigma range LOW HIGH, in pixels of a 1242-wide KITTI frame.")
@opt("--noise-prob", default=0.5, type=P, help="Probability of Poisson-Gaussian sensor noise.")
@opt("--noise-full-well", nargs=2, default=(3000.0, 20000.0), type=click.FloatRange(1),
     help="Full-well range LOW HIGH (electrons at white); lower is noisier.")
@opt("--jpeg-prob", default=0.2, type=P, help="Probability of a JPEG re-encode (quality 50-95).")
@opt("--cutout-prob", default=0.25, type=P,
     help="Probability of 1-3 grey/noise rectangles (no box covered more than half).")
@opt("--randconv-prob", default=0.0, type=P,
     help="Probability of RandConv-mix texture randomisation (a random convolution, its size "
          "drawn from --randconv-kernel, mixed with the image; detector/augment.py).")
@opt("--randconv-kernel", "randconv_kernels", multiple=True, type=click.IntRange(1), default=(1, 3, 5, 7),
     help="RandConv kernel sizes drawn uniformly (odd; repeat the option: --randconv-kernel 1 "
          "--randconv-kernel 3).")
@opt("--randconv-keep-below", default=0.0, type=click.FloatRange(0),
     help="Boxes lower than this (pixels of a 1242-wide KITTI frame) keep their own pixels under "
          "a random convolution, as do as many same-sized decoy patches (detector/augment.py); "
          "0: the whole image is convolved.")
@opt("--randconv-consistency", default=0.0, type=click.FloatRange(0),
     help="Weight of RandConv's consistency term; > 0 builds each batch of --batch images from --batch/2 "
          "samples, each seen without and with a random convolution, and adds this times a divergence of "
          "their objectness (--randconv-consistency-target; detector/loss.py). Needs --randconv-prob 0.")
@opt("--randconv-consistency-target", default="mutual", type=click.Choice(["mutual", "plain"]),
     help="mutual: Jensen-Shannon divergence, both views learn from it; plain: KL from the plain "
          "view's objectness, held fixed, to the convolved view's.")
@opt("--mixup", default="none", type=click.Choice(["none", "mixup", "thresholded"]),
     help="004 Mixup: plain, or only when the two images' boxes overlap below --mixup-iou.")
@stack(opt("--mixup-prob", default=0.5, type=P), opt("--mixup-iou", default=0.4, type=P))
@opt("--close-mosaic", default=3, type=click.IntRange(0),
     help="Last epochs without mosaic/zoom/Mixup (plain letterboxed images; flips, HSV and "
          "the photometric set stay as set).")
@split_option("--train-split", "train", "Training frames: ImageSets/NAME.txt of each --data; 'all': all.")
@click.option("--val-data", type=DATASET, metavar="ROOT", help="Evaluation root [default: the first --data].")
@split_option("--val-split", "val", "Evaluation frames: ImageSets/NAME.txt of the evaluation root; 'all': all.")
@opt("--eval-every", default=1, type=click.IntRange(0), help="Epochs between 2D AP evaluations (0: never).")
@click.option("--init", "init_weights", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Start from these weights (fine-tuning, e.g. real KITTI from synthetic); keeps their anchors.")
@stack(opt("--seed", default=0, type=click.IntRange(0)), opt("--threads", default=2, type=click.IntRange(1)))
@click.option("--resume", is_flag=True, help="Continue from OUT/last.pt.")
def train_detector(out: Path, resume: bool, **options) -> None:
    """Train the FlexiNet 2D detector (Car with Van, Pedestrian, Cyclist) on --data (one or more
    roots; the split applies to each)."""
    from detector.train import config_from_options, train
    from kitti.errors import KittiFormatError

    try:
        row = train(config_from_options(out=out, **options), resume=resume)
    except (KittiFormatError, ValueError, FileNotFoundError) as e:
        raise click.ClickException(str(e)) from None
    click.echo(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))
    click.echo(f"weights: {out / 'weights.pt'}")
