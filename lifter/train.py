"""Training of the size and orientation network on any KITTI-format dataset.

Samples: every labelled Car/Van/Pedestrian/Cyclist (Truck as Car) with a 2D box at least MIN_HEIGHT
px high, truncation <= MAX_TRUNC, occlusion <= 2. Crops are taken once with context around the box
(CONTEXT x its size), so each epoch can jitter the box like a detector's without rereading images.
The thesis's optimiser (SGD lr 1e-3, momentum 0.9) needs far more epochs than this CPU affords;
Adam (003's choice) with a cosine schedule is used, with the thesis's early stop (10 epochs without
improvement of the validation loss).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.io import atomic_path, atomic_write_text

from .crops import crop, jitter_box, to_tensor_layout
from .multibin import decode, encode, wrap
from .network import CLASS_OF, CLASSES, NetConfig, SizeOrientationNet, loss_fn
from .predictor import forward_mirrored

MIN_HEIGHT = 15.0
MAX_TRUNC = 0.5
CONTEXT = 1.3
PATIENCE = 10


@dataclass
class Samples:
    crops: np.ndarray   # (N, C, C, 3) uint8 context crops, C = round(CONTEXT * S)
    cls: np.ndarray     # (N,)
    dims: np.ndarray    # (N, 3) h, w, l
    alpha: np.ndarray   # (N,)


def collect(ds: KittiDataset, ids: list[str], size: int, desc: str) -> Samples:
    c = int(round(CONTEXT * size))
    crops, cls, dims, alpha = [], [], [], []
    for fid in tqdm(ids, desc=f"crops {desc}", leave=False):
        objs = [o for o in ds.labels(fid) if o.type in CLASS_OF and o.height_px >= MIN_HEIGHT
                and o.truncated <= MAX_TRUNC and o.occluded <= 2]
        if not objs:
            continue
        img = ds.image(fid)
        for o in objs:
            ctr = (o.bbox[:2] + o.bbox[2:]) / 2
            half = (o.bbox[2:] - o.bbox[:2]) * CONTEXT / 2
            crops.append(crop(img, np.concatenate([ctr - half, ctr + half]), c))
            cls.append(CLASS_OF[o.type])
            dims.append([o.h, o.w, o.l])
            alpha.append(o.alpha)
    if not crops:
        raise ValueError(f"{ds.root}: no usable labelled objects in the {desc} frames")
    return Samples(np.stack(crops), np.array(cls), np.array(dims, dtype=np.float32),
                   np.array(alpha))


def batch(s: Samples, idx: np.ndarray, size: int, rng: np.random.Generator | None):
    """Tensors for samples idx; with rng: jittered box, mirror, brightness/contrast."""
    c = s.crops.shape[1]
    lo = c * (1 - 1 / CONTEXT) / 2
    box = np.array([lo, lo, c - lo, c - lo])
    out = np.empty((len(idx), size, size, 3), dtype=np.uint8)
    alpha = s.alpha[idx].copy()
    for k, i in enumerate(idx):
        b = jitter_box(box, rng) if rng is not None else box
        img = crop(s.crops[i], b, size)
        if rng is not None:
            if rng.random() < 0.5:
                img = img[:, ::-1]
                alpha[k] = wrap(np.pi - alpha[k])
            gain, bias = rng.uniform(0.75, 1.25), rng.uniform(-20, 20)
            img = cv2.convertScaleAbs(img, alpha=gain, beta=bias)
        out[k] = img
    best, cs, cover = encode(alpha)
    return (torch.from_numpy(to_tensor_layout(out)), torch.from_numpy(s.cls[idx]),
            torch.from_numpy(s.dims[idx]), torch.from_numpy(best), torch.from_numpy(cs).float(),
            torch.from_numpy(cover))


def class_means(s: Samples) -> list[list[float]]:
    default = NetConfig().class_means
    return [s.dims[s.cls == k].mean(axis=0).round(4).tolist() if (s.cls == k).any() else default[k]
            for k in range(len(CLASSES))]


@torch.no_grad()
def errors(net: SizeOrientationNet, s: Samples, size: int, bs: int = 128,
           mirror: bool = False) -> tuple[float, np.ndarray, np.ndarray]:
    """The mean loss on samples, each sample's absolute size errors (N, 3, m) and its absolute
    alpha error (N, deg); `mirror` averages each crop with its mirror image as inference does
    (`lifter.predictor.forward_mirrored`)."""
    net.eval()
    losses, dims_err, ang_err = [], [], []
    for start in range(0, len(s.cls), bs):
        idx = np.arange(start, min(start + bs, len(s.cls)))
        x, cls, dims_t, bin_t, cs_t, cover_t = batch(s, idx, size, None)
        out = forward_mirrored(net, x, cls, mirror)
        loss, _ = loss_fn(out, dims_t, bin_t, cs_t, cover_t)
        losses.append(float(loss) * len(idx))
        dims_err.append(np.abs(out[0].numpy() - dims_t.numpy()))
        a = decode(out[1].numpy(), out[2].numpy())
        ang_err.append(np.abs(wrap(a - s.alpha[idx])))
    return sum(losses) / len(s.cls), np.concatenate(dims_err), np.rad2deg(np.concatenate(ang_err))


def evaluate(net: SizeOrientationNet, s: Samples, size: int, bs: int = 128,
             mirror: bool = False) -> dict[str, float]:
    """Loss, size and alpha errors on samples (`errors`), summed up. Training validates without
    the mirror, as it did when the shipped weights were trained: their documented commands pick
    the same epoch."""
    return summary(*errors(net, s, size, bs, mirror))


def summary(loss: float, de: np.ndarray, ae: np.ndarray) -> dict[str, float]:
    """`errors`' per-sample figures as training logs them: mean loss, size MAE, median alpha
    error and the share within 30 degrees."""
    return {"loss": loss, "dims_mae_m": float(de.mean()),
            "alpha_median_deg": float(np.median(ae)), "alpha_within_30deg": float((ae < 30).mean()),
            "n": len(ae)}


def _split_ids(ds: KittiDataset, root: Path, train_split: str | None,
               val_split: str | None) -> tuple[list[str], list[str]]:
    """Training and validation frames; without validation frames, every 10th training frame is
    held out, as the best epoch is picked on them."""
    if train_split and (root / "ImageSets" / f"{train_split}.txt").exists():
        tr_ids = ds.ids(train_split)
        va_ids = ds.ids(val_split) if val_split and (root / "ImageSets" / f"{val_split}.txt").exists() else []
    else:
        tr_ids, va_ids = ds.ids(), []
    if not va_ids:
        va_ids, tr_ids = tr_ids[::10], [f for i, f in enumerate(tr_ids) if i % 10]
    return tr_ids, va_ids


def _network(tr: Samples, crop_size: int, width: float,
             init: str | Path | None) -> tuple[SizeOrientationNet, NetConfig]:
    """A fresh network with the training data's class means, or (fine-tuning) the init weights,
    whose class means stay. The fresh one is built either way: it draws from torch's seeded RNG."""
    cfg = NetConfig(width=width, crop=crop_size, class_means=class_means(tr))
    net = SizeOrientationNet(cfg)
    if init is not None:
        ck = torch.load(init, map_location="cpu", weights_only=False)
        net = SizeOrientationNet(NetConfig(**ck["config"]) if isinstance(ck.get("config"), dict)
                                 else ck["config"])
        net.load_state_dict(ck["model"])
        cfg = net.cfg
        if (cfg.crop, cfg.width) != (crop_size, width):
            raise ValueError(f"--init {init}: crop {net.cfg.crop} / width {net.cfg.width} differ from "
                             f"--crop-size {crop_size} / --width {width}")
    return net, cfg


def _resume(path: Path, net: SizeOrientationNet, opt: torch.optim.Optimizer,
            sched: torch.optim.lr_scheduler.LRScheduler) -> tuple[int, float, int]:
    """Loads the training state of last.pt; returns the next epoch, the best loss and the stale count."""
    ck = torch.load(path, map_location="cpu", weights_only=False)
    net.load_state_dict(ck["model"])
    opt.load_state_dict(ck["optim"])
    sched.load_state_dict(ck["sched"])
    return ck["epoch"] + 1, ck["best_loss"], ck["stale"]


def _train_epoch(net: SizeOrientationNet, tr: Samples, opt: torch.optim.Optimizer, rng: np.random.Generator,
                 crop_size: int, batch_size: int, desc: str) -> bool:
    """One pass over the training samples in rng's order; returns whether any step was taken
    (the schedule advances only then)."""
    net.train()
    perm = rng.permutation(len(tr.cls))
    bar = tqdm(range(0, len(perm), batch_size), desc=desc, leave=False)
    stepped = False
    for start in bar:
        idx = perm[start:start + batch_size]
        if len(idx) < 2:  # batch norm needs two samples
            continue
        x, cls, dims_t, bin_t, cs_t, cover_t = batch(tr, idx, crop_size, rng)
        loss, parts = loss_fn(net(x, cls), dims_t, bin_t, cs_t, cover_t)
        opt.zero_grad()
        loss.backward()
        opt.step()
        stepped = True
        bar.set_postfix(loss=f"{loss.item():.3f}", **{k: f"{v:.3f}" for k, v in parts.items()})
    return stepped


def _save_epoch(out: Path, ck: dict, improved: bool) -> None:
    """last.pt every epoch (for resume), best.pt (what is served) when the validation loss improved,
    and the epoch's line in log.jsonl."""
    with atomic_path(out / "last.pt") as tmp:
        torch.save(ck, tmp)
    if improved:
        with atomic_path(out / "best.pt") as tmp:
            torch.save({k: ck[k] for k in ("model", "config", "epoch", "metrics", "seed", "data")}, tmp)
    with open(out / "log.jsonl", "a") as f:
        f.write(json.dumps(ck["metrics"]) + "\n")


def train(data: str | Path, out: str | Path, epochs: int = 30, crop_size: int = 96,
          width: float = 0.5, batch_size: int = 64, lr: float = 2e-3, seed: int = 0,
          threads: int = 2, train_split: str | None = "train", val_split: str | None = "val",
          resume: bool = False, init: str | Path | None = None) -> dict:
    """Trains into `out` (last.pt, best.pt, log.jsonl, summary.json) and returns the summary;
    stops after PATIENCE epochs without a better validation loss."""
    torch.manual_seed(seed)
    torch.set_num_threads(threads)
    rng = np.random.default_rng(seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ds = KittiDataset(data)
    tr_ids, va_ids = _split_ids(ds, Path(data), train_split, val_split)
    tr = collect(ds, tr_ids, crop_size, "train")
    va = collect(ds, va_ids, crop_size, "val")
    net, cfg = _network(tr, crop_size, width, init)
    opt = torch.optim.Adam(net.parameters(), lr=lr, weight_decay=1e-5)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=epochs)
    start_epoch, best_loss, stale = 0, float("inf"), 0
    if resume and (out / "last.pt").exists():
        start_epoch, best_loss, stale = _resume(out / "last.pt", net, opt, sched)
        rng = np.random.default_rng([seed, start_epoch])
    log = []
    for epoch in range(start_epoch, epochs):
        if _train_epoch(net, tr, opt, rng, crop_size, batch_size, f"epoch {epoch + 1}/{epochs}"):
            sched.step()
        metrics = {"epoch": epoch + 1, **evaluate(net, va, crop_size)}
        log.append(metrics)
        tqdm.write(json.dumps(metrics))
        improved = metrics["loss"] < best_loss
        best_loss, stale = (metrics["loss"], 0) if improved else (best_loss, stale + 1)
        _save_epoch(out, {"model": net.state_dict(), "config": cfg.to_dict(), "epoch": epoch,
                          "metrics": metrics, "optim": opt.state_dict(), "sched": sched.state_dict(),
                          "best_loss": best_loss, "stale": stale, "seed": seed, "data": str(data)}, improved)
        if stale >= PATIENCE:
            break
    summary = {"best_val_loss": best_loss, "epochs_run": len(log), "train_samples": len(tr.cls),
               "val_samples": len(va.cls), "config": cfg.to_dict(), "last": log[-1] if log else None}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2))
    return summary
