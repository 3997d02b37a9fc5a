"""The figures of the report: lidar.png, images.png, labels.png (sim and real overlaid as
normalised histograms, one subplot per statistic) and frames.png (the first frames of each side,
one above the other, to look at). Fixed size, dpi and no software tag, so the same data give the
same bytes."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from kitti.dataset import KittiDataset
from kitti.io import atomic_path

from .compare import Comparison
from .labels import CLASSES

DPI = 90
FRAMES_SHOWN = 2  # per side in frames.png
COLOURS = {"sim": "tab:orange", "real": "tab:blue"}


def _sides(comp: Comparison):
    return (("sim", comp.sim), ("real", comp.real))


def _absent(ax, title: str) -> None:
    ax.set_title(title, fontsize=9)
    ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)


def _hist(ax, comp: Comparison, key: str, title: str, log: bool = False) -> None:
    """A pooled fixed-bin histogram, normalised to sum 1."""
    if not any(d.hists[key].counts.sum() for _, d in _sides(comp)):
        return _absent(ax, title)
    for name, d in _sides(comp):
        h = d.hists[key]
        ax.stairs(h.normalised(), h.edges, label=name, color=COLOURS[name])
    ax.set_title(title, fontsize=9)
    ax.set_yscale("log" if log else "linear")
    ax.legend(fontsize=7)


def _values(ax, comp: Comparison, key: str, title: str, bins: int = 20) -> None:
    """Per-frame (or per-object) values of both sides on shared bins."""
    vals = {name: d.get(key)[np.isfinite(d.get(key))] for name, d in _sides(comp)}
    both = np.concatenate(list(vals.values()))
    if not len(both):
        return _absent(ax, title)
    edges = np.histogram_bin_edges(both, bins)
    for name, v in vals.items():
        counts = np.histogram(v, edges)[0]
        ax.stairs(counts / max(counts.sum(), 1), edges, label=name, color=COLOURS[name])
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)


def _per_ring(ax, comp: Comparison, key: str, title: str) -> None:
    if not any(key in d.rows for _, d in _sides(comp)):
        return _absent(ax, title)
    for name, d in _sides(comp):
        if key in d.rows:
            with warnings.catch_warnings():  # a ring empty in every frame stays NaN
                warnings.simplefilter("ignore", RuntimeWarning)
                med = np.nanmedian(d.rows[key], axis=0)
            ax.plot(med, ".-", ms=3, label=name, color=COLOURS[name])
    ax.set_xlabel("ring (0 = top)", fontsize=8)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)


def _car_points(ax, comp: Comparison) -> None:
    title = "points in each Car's box vs distance (m)"
    if not any(len(d.get("lidar.car_points")) for _, d in _sides(comp)):
        return _absent(ax, title)
    for name, d in _sides(comp):
        ax.scatter(d.get("lidar.car_distance_m"), d.get("lidar.car_points"), s=6, alpha=0.6,
                   label=name, color=COLOURS[name])
    ax.set_yscale("symlog", linthresh=10)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)


def _classes(ax, comp: Comparison) -> None:
    title = "objects per frame by class (mean)"
    if not any("labels.class_counts" in d.rows for _, d in _sides(comp)):
        return _absent(ax, title)
    x = np.arange(len(CLASSES))
    for i, (name, d) in enumerate(_sides(comp)):
        rows = d.rows.get("labels.class_counts")
        mean = rows.mean(axis=0) if rows is not None else np.zeros(len(CLASSES))
        ax.bar(x + (i - 0.5) * 0.4, mean, 0.4, label=name, color=COLOURS[name])
    ax.set_xticks(x, CLASSES, rotation=30, fontsize=7)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7)


def write_plots(comp: Comparison, out_dir: Path) -> list[str]:
    """Write the three figures; returns their file names."""
    from matplotlib.figure import Figure

    panels = {
        "lidar.png": [
            lambda ax: _hist(ax, comp, "lidar.range_m", "range (m)", log=True),
            lambda ax: _hist(ax, comp, "lidar.reflectance", "reflectance", log=True),
            lambda ax: _values(ax, comp, "lidar.points", "points per sweep"),
            lambda ax: _per_ring(ax, comp, "lidar.ring_returns", "returns per ring (median)"),
            lambda ax: _per_ring(ax, comp, "lidar.ring_elevation_deg", "ring elevation (deg)"),
            lambda ax: _car_points(ax, comp)],
        "images.png": [
            lambda ax: _hist(ax, comp, "images.grey", "grey level"),
            lambda ax: _hist(ax, comp, "images.saturation", "HSV saturation"),
            lambda ax: _hist(ax, comp, "images.gradient", "gradient magnitude", log=True),
            lambda ax: _values(ax, comp, "images.mean_abs_dx", "mean |dI/dx| per frame"),
            lambda ax: _values(ax, comp, "images.edge_density", "edge density per frame"),
            lambda ax: _values(ax, comp, "images.png_bytes", "PNG size per frame (bytes)")],
        "labels.png": [
            lambda ax: _classes(ax, comp),
            lambda ax: _hist(ax, comp, "labels.distance_m", "object distance (m)"),
            lambda ax: _hist(ax, comp, "labels.occlusion", "occlusion level"),
            lambda ax: _hist(ax, comp, "labels.truncation", "truncation"),
            lambda ax: _hist(ax, comp, "labels.box_height_px", "2D box height (px)"),
            lambda ax: _hist(ax, comp, "labels.proj_gap_px", "2D vs projected 3D box (px)")],
    }
    names = list(panels)
    if comp.sim.frames and comp.real.frames:
        _frames(comp, out_dir / "frames.png")
        names.append("frames.png")
    for name, draw in panels.items():
        fig = Figure(figsize=(13, 7))
        for ax, fn in zip(fig.subplots(2, 3).ravel(), draw):
            fn(ax)
        fig.suptitle(f"{name[:-4]}: sim {comp.sim.root} vs real {comp.real.root}", fontsize=10)
        fig.subplots_adjust(left=0.05, right=0.98, bottom=0.08, top=0.91, wspace=0.2, hspace=0.35)
        with atomic_path(out_dir / name) as tmp:
            fig.savefig(tmp, format="png", dpi=DPI, metadata={"Software": None})
    return names


def _frames(comp: Comparison, path: Path) -> None:
    """The first FRAMES_SHOWN frames read of each side, generated and real alternating."""
    import cv2
    from matplotlib.figure import Figure

    shown = [(side, d, fid) for i in range(FRAMES_SHOWN)
             for side, d in (("sim", comp.sim), ("real", comp.real)) if i < len(d.frames)
             for fid in [d.frames[i]]]
    fig = Figure(figsize=(12.42, 3.9 * len(shown)))
    for ax, (side, d, fid) in zip(np.atleast_1d(fig.subplots(len(shown), 1)), shown):
        img = cv2.imread(str(KittiDataset(d.root).image_path(fid)), cv2.IMREAD_COLOR)
        ax.imshow(img[..., ::-1], interpolation="nearest")
        ax.set_title(f"{side}: {d.root} frame {fid}", fontsize=9, color=COLOURS[side])
        ax.set_axis_off()
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.97, hspace=0.12)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100, metadata={"Software": None})
