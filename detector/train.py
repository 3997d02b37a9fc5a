"""Training loop: SGD with the thesis's settings (lr 0.01, momentum 0.94, batch 16), linear
warm-up, cosine or step decay, an exponential moving average of the weights (what is evaluated
and shipped), a checkpoint every epoch with exact resume, and per-epoch loss and 2D AP
(through kitti.eval) in a CSV and a plot.

Weight decay: 000 prints "0.05x10-1" (= 5e-3, likely garbled); the default here is the usual
5e-4 of YOLOv5-style detectors, and `--weight-decay 0.005` gives the literal reading.
"""
from __future__ import annotations

import copy
import math
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from detector.anchors import best_possible_recall, kmeans_anchors
from detector.augment import AugmentConfig, Augmenter
from detector.boxes import input_size_for
from detector.data import CLASSES, DetectionData
from detector.infer import Detector, save_checkpoint
from detector.loss import CONSISTENCY_TARGETS, DetectionLoss
from detector.model import PRESETS, FlexiNet, ModelConfig
from kitti.dataset import KittiDataset
from kitti.eval.protocol import DIFFICULTIES
from kitti.io import atomic_write_text


@dataclass(frozen=True)
class TrainConfig:
    data: tuple[str, ...]              # training roots (a single path is accepted too)
    out: str
    preset: str = "small"
    epochs: int = 30
    img_size: tuple[int, int] | None = None  # network input (w, h); None: 640 wide, height from the data
    batch: int = 16
    lr: float = 0.01
    momentum: float = 0.94
    weight_decay: float = 5e-4
    warmup_epochs: float = 1.0
    schedule: str = "cosine"     # cosine | step
    final_lr_factor: float = 0.05
    activation: str = "hardswish"
    box_loss: str = "diou"
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    randconv_consistency: float = 0.0  # > 0: batches of RandConv pairs (Augmenter.pair) and this weight on
                                       # their objectness consistency (DetectionLoss.pair_consistency)
    randconv_consistency_target: str = "mutual"  # mutual | plain (DetectionLoss.pair_consistency)
    close_mosaic: int = 3        # last epochs on plain letterboxed images, flips, HSV and photometric
                                 # set kept (AugmentConfig.closing: why)
    train_split: str | None = "train"  # ImageSets name; None: every frame of the root
    val_split: str | None = "val"      # likewise, for the per-epoch evaluation
    val_data: str | None = None        # evaluation root (default: the training root)
    eval_every: int = 1                # epochs between evaluations; 0: never
    ema_decay: float = 0.999
    init: str | None = None            # start from these weights (fine-tuning); anchors come with them
    seed: int = 0
    threads: int = 2
    progress: bool = True

    def __post_init__(self):
        if isinstance(self.data, str):
            object.__setattr__(self, "data", (self.data,))
        if not self.data:
            raise ValueError("at least one training root is needed")
        if self.preset not in PRESETS:
            raise ValueError(f"unknown preset {self.preset!r}; choose one of {sorted(PRESETS)}")
        if self.schedule not in ("cosine", "step"):
            raise ValueError(f"schedule must be cosine or step, got {self.schedule!r}")
        if self.epochs < 1 or self.batch < 1:
            raise ValueError("epochs and batch must be at least 1")
        if self.img_size is not None and (self.img_size[0] % 32 or self.img_size[1] % 32):
            raise ValueError(f"img_size must be multiples of 32, got {self.img_size}")
        if self.randconv_consistency_target not in CONSISTENCY_TARGETS:
            raise ValueError(f"randconv_consistency_target must be one of {CONSISTENCY_TARGETS}, "
                             f"got {self.randconv_consistency_target!r}")
        if self.randconv_consistency < 0:
            raise ValueError(f"randconv_consistency must be >= 0, got {self.randconv_consistency}")
        if self.randconv_consistency > 0:
            if self.batch % 2:
                raise ValueError(f"randconv_consistency trains on pairs: batch must be even, got {self.batch}")
            if not self.augment.photometric or self.augment.randconv_prob > 0:
                raise ValueError("randconv_consistency draws its own RandConv view: it needs the photometric "
                                 f"set on and augment randconv_prob 0, got photometric "
                                 f"{self.augment.photometric}, randconv_prob {self.augment.randconv_prob}")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["augment"] = asdict(self.augment)
        return d


# The augmentation's settings that `testbed train-detector` takes by their AugmentConfig names.
AUGMENT_OPTIONS = ("mosaic", "scale", "fliplr", "photometric", "blur_sigma", "noise_prob",
                   "noise_full_well", "jpeg_prob", "cutout_prob", "randconv_prob", "randconv_kernels",
                   "randconv_keep_below", "mixup", "mixup_prob", "mixup_iou")


def config_from_options(data, out, *, hsv: bool = True, wb_gain: float = AugmentConfig.gain,
                        img_size=None, train_split: str = "train", val_split: str = "val",
                        val_data=None, init_weights=None, **options) -> TrainConfig:
    """The TrainConfig of `testbed train-detector`'s options: `data` one root or several, paths
    as strings, `hsv` the colour jitter on or off, `wb_gain` the white balance's gain, a split
    'all' every frame (None); AUGMENT_OPTIONS by AugmentConfig's names, the rest by TrainConfig's."""
    aug = {k: options.pop(k) for k in AUGMENT_OPTIONS if k in options}
    aug.update({k: tuple(aug[k]) for k in ("blur_sigma", "noise_full_well", "randconv_kernels") if k in aug})
    augment = AugmentConfig(hsv=AugmentConfig().hsv if hsv else (0.0, 0.0, 0.0), gain=wb_gain, **aug)
    roots = (data,) if isinstance(data, (str, Path)) else data
    return TrainConfig(data=tuple(str(d) for d in roots), out=str(out),
                       img_size=tuple(img_size) if img_size else None, augment=augment,
                       train_split=None if train_split == "all" else train_split,
                       val_split=None if val_split == "all" else val_split,
                       val_data=str(val_data) if val_data else None,
                       init=str(init_weights) if init_weights else None, **options)


class ModelEMA:
    """Exponential moving average of the weights; the decay ramps up so early, poor weights fade fast."""

    def __init__(self, model: nn.Module, decay: float, updates: int = 0):
        self.ema = copy.deepcopy(model).eval()
        self.decay = decay
        self.updates = updates
        for p in self.ema.parameters():
            p.requires_grad_(False)

    @torch.no_grad()
    def update(self, model: nn.Module) -> None:
        self.updates += 1
        d = self.decay * (1 - math.exp(-self.updates / 500))
        msd = model.state_dict()
        for k, v in self.ema.state_dict().items():
            if v.dtype.is_floating_point:
                v.mul_(d).add_(msd[k].detach(), alpha=1 - d)
            else:
                v.copy_(msd[k])


def lr_factor(cfg: TrainConfig, epoch_pos: float) -> float:
    """Learning-rate multiplier at a fractional epoch (after warm-up)."""
    f = cfg.final_lr_factor
    if cfg.schedule == "cosine":
        return f + (1 - f) * 0.5 * (1 + math.cos(math.pi * epoch_pos / cfg.epochs))
    return 1.0 if epoch_pos < 0.7 * cfg.epochs else (0.1 if epoch_pos < 0.9 * cfg.epochs else 0.01)


def make_optimizer(model: nn.Module, cfg: TrainConfig) -> torch.optim.SGD:
    """SGD with Nesterov momentum; weight decay on conv weights only (not on BN or biases)."""
    decay, no_decay = [], []
    for name, p in model.named_parameters():
        (decay if p.ndim > 1 else no_decay).append(p)
    return torch.optim.SGD([{"params": no_decay, "weight_decay": 0.0},
                            {"params": decay, "weight_decay": cfg.weight_decay}],
                           lr=cfg.lr, momentum=cfg.momentum, nesterov=True)


def collate(samples) -> tuple[torch.Tensor, torch.Tensor]:
    """Images (B,3,H,W) in [0,1]; targets (M,6): image index, class, cx, cy, w, h (pixels)."""
    imgs = torch.from_numpy(np.stack([s.image for s in samples])).permute(0, 3, 1, 2).float().div_(255)
    rows = []
    for i, s in enumerate(samples):
        b = s.boxes
        if len(b):
            rows.append(np.column_stack((np.full(len(b), i), s.classes, (b[:, 0] + b[:, 2]) / 2,
                                         (b[:, 1] + b[:, 3]) / 2, b[:, 2] - b[:, 0], b[:, 3] - b[:, 1])))
    t = torch.from_numpy(np.concatenate(rows)).float() if rows else torch.zeros((0, 6))
    return imgs, t


def fit_anchors(data: DetectionData, seed: int) -> tuple[tuple[float, float], ...]:
    wh = data.box_sizes()
    if len(wh) < 9:
        raise ValueError(f"{', '.join(data.roots)}: only {len(wh)} labelled boxes of {CLASSES}; need at least 9 for anchors")
    a = kmeans_anchors(wh, 9, np.random.default_rng(seed))
    return tuple((float(w), float(h)) for w, h in a)


def evaluate_model(model: FlexiNet, input_size: tuple[int, int], root: str, split: str | None,
                   batch: int = 8, progress: bool = False):
    """2D AP of a model on a split through kitti.eval (scores down to 0.001, as AP needs), each
    image read once (as training runs logged it before `testbed detect` read images mirrored too:
    a documented run still writes the same history)."""
    from kitti.eval import evaluate
    det = Detector((model.eval(),), input_size, CLASSES, mirror=False)
    ds = KittiDataset(root)
    ids = ds.ids(split)
    gt, dt = {}, {}
    for i in tqdm(range(0, len(ids), batch), desc="eval", disable=not progress, leave=False):
        chunk = ids[i:i + batch]
        for fid, d in zip(chunk, det.detect([ds.image(f) for f in chunk], conf_threshold=0.001)):
            dt[fid] = det.to_objects(d)
            gt[fid] = ds.labels(fid)
    return evaluate(gt, dt, classes=CLASSES, metrics=("2d",))


CSV_FIELDS = ["epoch", "lr", "loss", "box", "obj", "cls", "cons", "seconds"] + \
    [f"{c}_2d_R40_{d}" for c in CLASSES for d in DIFFICULTIES]


def _checkpoints(cfg: TrainConfig, ck_path: Path,
                 resume: bool) -> tuple[TrainConfig, dict | None, dict | None]:
    """The checkpoint to resume from and the weights to start from (at most one of them); the
    network input size comes with either, since the weights only fit that size."""
    ck = torch.load(ck_path, map_location="cpu", weights_only=True) if resume and ck_path.is_file() else None
    init = torch.load(cfg.init, map_location="cpu", weights_only=True) if cfg.init and ck is None else None
    if isinstance(init, dict) and "members" in init:
        raise ValueError(f"{cfg.init}: an ensemble of {len(init['members'])} networks; start from one of them")
    if ck is not None:
        cfg = replace(cfg, img_size=tuple(ck["input_size"]))
    elif init is not None and cfg.img_size is None:
        cfg = replace(cfg, img_size=tuple(init["input_size"]))
    return cfg, ck, init


def _model_config(cfg: TrainConfig, data: DetectionData, ck: dict | None, init: dict | None) -> ModelConfig:
    """The architecture of the checkpoint or the init weights, else the preset with anchors fitted
    to this data."""
    if ck is not None:
        return ModelConfig.from_dict(ck["model_cfg"])
    if init is not None:
        return ModelConfig.from_dict(init["model_cfg"])
    return ModelConfig.from_preset(cfg.preset, num_classes=len(CLASSES), activation=cfg.activation,
                                   anchors=fit_anchors(data, cfg.seed))


def _restore(ck: dict, model: FlexiNet, ema: ModelEMA, opt: torch.optim.SGD) -> tuple[int, list[dict]]:
    """Loads a checkpoint's full training state (exact resume); returns the next epoch and the history."""
    model.load_state_dict(ck["train_model"])
    ema.ema.load_state_dict(ck["model"])
    ema.updates = int(ck["ema_updates"])
    opt.load_state_dict(ck["optimizer"])
    return int(ck["epoch"]) + 1, [dict(r) for r in ck["history"]]


def _write_anchors(out: Path, data: DetectionData, anchors: tuple[tuple[float, float], ...]) -> None:
    """anchors.txt, with the best possible recall of the anchors on the training boxes."""
    bpr = best_possible_recall(data.box_sizes(), np.array(anchors))
    atomic_write_text(out / "anchors.txt", "".join(f"{w:.2f} {h:.2f}\n" for w, h in anchors)
                      + f"# best possible recall {bpr:.4f}\n")


def _set_lr(opt: torch.optim.SGD, cfg: TrainConfig, it: int, epoch_pos: float, warmup_iters: int) -> None:
    """Learning rate and momentum of one iteration: the schedule, ramped up during warm-up."""
    lr_f = lr_factor(cfg, epoch_pos)
    for g in opt.param_groups:
        if it < warmup_iters:
            w = it / warmup_iters
            g["lr"] = cfg.lr * lr_f * w
            g["momentum"] = 0.8 + (cfg.momentum - 0.8) * w
        else:
            g["lr"] = cfg.lr * lr_f
            g["momentum"] = cfg.momentum


def _train_epoch(cfg: TrainConfig, epoch: int, n: int, model: FlexiNet, criterion: DetectionLoss,
                 opt: torch.optim.SGD, ema: ModelEMA, aug: Augmenter) -> list[float]:
    """One epoch over the n images in an order seeded by (seed, epoch), so a resumed run repeats
    it exactly; returns the mean total, box, obj, cls and consistency losses per batch. With
    randconv_consistency a batch holds batch / 2 images, each as a RandConv pair, so an epoch has
    twice the iterations."""
    pairs = cfg.randconv_consistency > 0
    per = cfg.batch // 2 if pairs else cfg.batch
    nb = math.ceil(n / per)
    warmup_iters = max(round(cfg.warmup_epochs * nb), 1)
    model.train()
    acfg = cfg.augment if epoch < cfg.epochs - cfg.close_mosaic else cfg.augment.closing()
    order = np.random.default_rng([cfg.seed, epoch, 1 << 20]).permutation(n)
    sums = torch.zeros(5)
    bar = tqdm(range(nb), desc=f"epoch {epoch + 1}/{cfg.epochs}", disable=not cfg.progress, leave=False)
    for bi in bar:
        _set_lr(opt, cfg, epoch * nb + bi, epoch + bi / nb, warmup_iters)
        chunk = [int(i) for i in order[bi * per:(bi + 1) * per]]
        if pairs:
            imgs, targets = collate([v for i in chunk for v in aug.pair(i, epoch, acfg)])
        else:
            imgs, targets = collate([aug(i, epoch, acfg) for i in chunk])
        raw = model(imgs)
        loss, parts = criterion(raw, targets)
        if pairs:
            cons = cfg.randconv_consistency * criterion.pair_consistency(raw, cfg.randconv_consistency_target)
            loss = loss + cons
            parts = torch.cat((parts, (cons / imgs.shape[0]).detach().view(1)))
        else:
            parts = torch.cat((parts, parts.new_zeros(1)))
        opt.zero_grad(set_to_none=True)
        loss.backward()
        nn.utils.clip_grad_norm_(model.parameters(), 10.0)  # guards the first, large-loss steps
        opt.step()
        ema.update(model)
        sums += torch.cat((parts.sum().view(1), parts))
        bar.set_postfix(loss=f"{sums[0].item() / (bi + 1):.4f}")
    return (sums / nb).tolist()


def _add_ap(row: dict, cfg: TrainConfig, model: FlexiNet, img_size: tuple[int, int]) -> None:
    """Adds the model's 2D AP|R40 per class and difficulty on the validation split to the row."""
    res = evaluate_model(model, img_size, cfg.val_data or cfg.data[0], cfg.val_split)
    for c in CLASSES:
        for d, v in zip(DIFFICULTIES, res.ap[c]["2d"]["R40"]):
            row[f"{c}_2d_R40_{d}"] = float(v)


def train(cfg: TrainConfig, resume: bool = False, stop_after: int | None = None) -> dict:
    """Train; returns the last epoch's row. With resume, continues from out/last.pt exactly.
    stop_after ends this call after that many epochs (a time-boxed chunk; resume continues)."""
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    ck_path = out / "last.pt"
    cfg, ck, init = _checkpoints(cfg, ck_path, resume)
    img_size = cfg.img_size or _default_size(cfg.data[0], cfg.train_split)
    data = DetectionData(cfg.data, cfg.train_split, img_size, cfg.progress)
    mcfg = _model_config(cfg, data, ck, init)
    model = FlexiNet(mcfg)
    if init is not None:
        model.load_state_dict(init["model"])
    criterion = DetectionLoss(model.head, cfg.box_loss)
    opt = make_optimizer(model, cfg)
    ema = ModelEMA(model, cfg.ema_decay)
    start_epoch, history = _restore(ck, model, ema, opt) if ck is not None else (0, [])
    _write_anchors(out, data, mcfg.anchors)
    aug = Augmenter(data, cfg.augment, cfg.seed)
    n = len(data)
    row: dict = history[-1] if history else {}
    end_epoch = cfg.epochs if stop_after is None else min(cfg.epochs, start_epoch + stop_after)
    for epoch in range(start_epoch, end_epoch):
        t0 = time.time()
        avg = _train_epoch(cfg, epoch, n, model, criterion, opt, ema, aug)
        row = {"epoch": epoch + 1, "lr": opt.param_groups[0]["lr"], "loss": avg[0], "box": avg[1],
               "obj": avg[2], "cls": avg[3], "seconds": time.time() - t0}
        if cfg.randconv_consistency > 0:
            row["cons"] = avg[4]
        if cfg.eval_every and ((epoch + 1) % cfg.eval_every == 0 or epoch + 1 == cfg.epochs):
            _add_ap(row, cfg, ema.ema, img_size)
        history.append(row)
        save_checkpoint(ck_path, ema.ema, img_size, {
            "train_model": model.state_dict(), "optimizer": opt.state_dict(), "epoch": epoch,
            "ema_updates": ema.updates, "history": history, "train_config": _plain(cfg.to_dict())})
        write_history(out, history, plot="Car_2d_R40_moderate" in row or epoch + 1 == cfg.epochs)
    if end_epoch == cfg.epochs:
        save_checkpoint(out / "weights.pt", ema.ema, img_size, {"train_config": _plain(cfg.to_dict()),
                                                               "history": history})
    return row


def _plain(d):
    """Config dict with tuples as lists (loadable with weights_only)."""
    if isinstance(d, dict):
        return {k: _plain(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_plain(v) for v in d]
    return d


def _default_size(root: str, split: str | None) -> tuple[int, int]:
    ds = KittiDataset(root)
    ids = ds.ids(split)
    if not ids:
        raise ValueError(f"{root}: split {split!r} has no frames")
    w, h = ds.image_size(ids[0])
    return input_size_for(w, h, 640)


def write_history(out: Path, history: list[dict], plot: bool = True) -> None:
    """history.csv and (with plot) history.png: loss and 2D AP|R40 moderate per class per epoch."""
    lines = [",".join(CSV_FIELDS)]
    for r in history:
        lines.append(",".join("" if r.get(k) is None else (f"{r[k]:.6g}" if isinstance(r[k], float) else str(r[k]))
                              for k in CSV_FIELDS))
    atomic_write_text(out / "history.csv", "\n".join(lines) + "\n")
    if not plot:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kitti.io import atomic_path
    ep = [r["epoch"] for r in history]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for k in ("loss", "box", "obj", "cls", "cons"):
        if k in history[-1]:
            a1.plot(ep, [r.get(k) for r in history], label=k)
    a1.set_xlabel("epoch"); a1.set_ylabel("loss per image"); a1.set_yscale("log"); a1.legend()
    for c in CLASSES:
        key = f"{c}_2d_R40_moderate"
        pts = [(r["epoch"], r[key]) for r in history if key in r]
        if pts:
            a2.plot(*zip(*pts), marker="o", label=c)
    a2.set_xlabel("epoch"); a2.set_ylabel("2D AP|R40 moderate"); a2.set_ylim(0, 100)
    if a2.lines:
        a2.legend()
    fig.tight_layout()
    with atomic_path(out / "history.png") as tmp:
        fig.savefig(tmp, format="png", dpi=90)
    plt.close(fig)
