"""Pictures of a KITTI-format frame: the image with projected 3D boxes and a bird's-eye view of the
LiDAR points with the same boxes. Works on any KITTI-format root (ours or the real benchmark)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from kitti.boxes import EDGES, box_corners
from kitti.calib import Calibration
from kitti.dataset import KittiDataset
from kitti.labels import Object3D, read_label

CLASS_COLORS = {"Car": "#00d000", "Van": "#00a0a0", "Truck": "#a0a000", "Pedestrian": "#ff3030",
                "Person_sitting": "#ff8080", "Cyclist": "#ffd000", "Tram": "#b000b0",
                "Misc": "#b0b0b0", "Bus": "#ff8000"}
NEAR = 0.1


def _has_3d(o: Object3D) -> bool:
    return o.type != "DontCare" and o.h > 0 and o.w > 0 and o.l > 0 and o.location[2] > -999


def image_edges(obj: Object3D, calib: Calibration) -> list[np.ndarray]:
    """Projected 2D segments of the 12 box edges, each cut at the near plane."""
    c = box_corners(obj.box7[None])[0]
    segs = []
    for i, j in EDGES:
        a, b = c[i], c[j]
        if a[2] < NEAR and b[2] < NEAR:
            continue
        if a[2] < NEAR or b[2] < NEAR:
            t = (NEAR - a[2]) / (b[2] - a[2])
            cut = a + t * (b - a)
            a, b = (cut, b) if a[2] < NEAR else (a, cut)
        uv, _ = calib.rect_to_image(np.stack([a, b]))
        segs.append(uv)
    return segs


def draw_image(ax, image: np.ndarray, calib: Calibration, objects: list[Object3D],
               linestyle: str = "-") -> None:
    h, w = image.shape[:2]
    for o in objects:
        color = CLASS_COLORS.get(o.type, "white")
        if o.type == "DontCare":
            x1, y1, x2, y2 = o.bbox
            ax.add_patch(plt.Rectangle((x1, y1), x2 - x1, y2 - y1, fill=False, ec="#808080",
                                       lw=0.6, ls=":"))
            continue
        if not _has_3d(o):  # 2D-only detections
            x1, y1, x2, y2 = o.bbox
            ax.add_patch(plt.Rectangle((x1, y1), x2 - x1, y2 - y1, fill=False, ec=color, lw=0.8,
                                       ls=linestyle))
            continue
        for seg in image_edges(o, calib):
            ax.plot(seg[:, 0], seg[:, 1], color=color, lw=0.8, ls=linestyle)
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_axis_off()


def draw_bev(ax, points: np.ndarray | None, calib: Calibration, objects: list[Object3D],
             linestyle: str = "-", extent: float = 80.0) -> None:
    """Bird's-eye view in the LiDAR frame: x forward (up the page), y left (left of the page)."""
    if points is not None and len(points):
        keep = (points[:, 0] > -10) & (points[:, 0] < extent) & (np.abs(points[:, 1]) < extent / 2)
        p = points[keep]
        ax.scatter(-p[:, 1], p[:, 0], s=0.4, c=np.clip(p[:, 2], -2.0, 1.0), cmap="cool",
                   linewidths=0, rasterized=True)
    for o in objects:
        if not _has_3d(o):
            continue
        c = calib.rect_to_lidar(box_corners(o.box7[None])[0][:4])
        loop = np.vstack([c, c[:1]])
        color = CLASS_COLORS.get(o.type, "white")
        ax.plot(-loop[:, 1], loop[:, 0], color=color, lw=0.9, ls=linestyle)
        front = c[[0, 1]].mean(axis=0)  # corners 0-1 are the front face
        centre = c.mean(axis=0)
        ax.plot([-centre[1], -front[1]], [centre[0], front[0]], color=color, lw=0.9, ls=linestyle)
    ax.set_xlim(-extent / 2, extent / 2)
    ax.set_ylim(-10, extent)
    ax.set_aspect("equal")
    ax.set_facecolor("#101010")
    ax.set_xlabel("-y (m)")
    ax.set_ylabel("x (m)")


MIN_SCORE = 0.3  # result files keep a long low-score tail for AP; pictures show the confident boxes


def draw_frame(dataset: KittiDataset, fid: str, pred_dir: str | Path | None = None,
               title: str | None = None, min_score: float = MIN_SCORE):
    """Figure with the image (truth solid, predictions scoring at least `min_score` dashed) and
    the bird's-eye view."""
    image = dataset.image(fid)
    calib = dataset.calib(fid)
    label_path = dataset.path("label_2", fid, "txt")
    truth = read_label(label_path) if label_path.exists() else []
    pred = []
    if pred_dir is not None and (Path(pred_dir) / f"{fid}.txt").exists():
        pred = [o for o in read_label(Path(pred_dir) / f"{fid}.txt")
                if o.score is None or o.score >= min_score]
    h, w = image.shape[:2]
    fig = plt.figure(figsize=(16, 16 * 0.3), dpi=110)
    # the gap holds the bird's-eye view's tick labels and axis label clear of the image
    gs = fig.add_gridspec(1, 2, width_ratios=[w / h, 1.0], wspace=0.16)
    ax_img, ax_bev = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    ax_img.imshow(image)
    draw_image(ax_img, image, calib, truth, "-")
    draw_image(ax_img, image, calib, pred, "--")
    draw_bev(ax_bev, dataset.velodyne(fid), calib, truth, "-")
    draw_bev(ax_bev, None, calib, pred, "--")
    ax_img.set_title(title or f"{dataset.root.name} frame {fid}: truth solid"
                     + (f", predictions scoring >= {min_score:g} dashed" if pred_dir else ""),
                     fontsize=9)
    return fig
