"""Exact synthetic frames for the lifter tests: boxes on a flat road scanned by an analytic
rotating LiDAR (ray/box slab intersection), so every return and every 2D box is known exactly."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kitti.boxes import alpha_from_rotation_y, project_boxes, rot_y
from kitti.calib import Calibration
from kitti.labels import Object3D

IMAGE_SIZE = (1242, 375)
CAMERA_HEIGHT = 1.65
PLANE = np.array([0.0, -1.0, 0.0, CAMERA_HEIGHT])  # y = 1.65 in the rect frame, normal up


@dataclass
class SynthFrame:
    calib: Calibration
    velodyne: np.ndarray   # (N, 4) float32 LiDAR frame
    hit_id: np.ndarray     # (N,) index of the box hit, -1 for the road
    objects: list[Object3D]


def scan(boxes7: np.ndarray, calib: Calibration, beams: int = 64, az_step_deg: float = 0.18,
         fov_deg: float = 50.0, max_range: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    """Returns (points rect (N,3), hit ids (N,)) of a beam fan from +2 to -24.9 degrees."""
    elev = np.deg2rad(np.linspace(2.0, -24.9, beams))
    az = np.deg2rad(np.arange(-fov_deg, fov_deg, az_step_deg))
    e, a = np.meshgrid(elev, az, indexing="ij")
    d_lidar = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1).reshape(-1, 3)
    m = calib.velo_to_rect
    d = d_lidar @ m[:3, :3].T
    o = m[:3, 3]
    t_best = np.full(len(d), np.inf)
    ids = np.full(len(d), -1)
    ndot = d @ PLANE[:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = -(o @ PLANE[:3] + PLANE[3]) / ndot
    t_best = np.where((ndot < 0) & (tg > 0), tg, np.inf)
    for k, b in enumerate(np.asarray(boxes7, dtype=float).reshape(-1, 7)):
        r = rot_y(b[6])[0]
        centre = b[:3] - np.array([0, b[3] / 2, 0])
        ol, dl = r.T @ (o - centre), d @ r  # local frame: x along l, y down, z along w
        half = np.array([b[5], b[3], b[4]]) / 2
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (-half - ol) / dl, (half - ol) / dl
        tn = np.nanmax(np.minimum(t1, t2), axis=1)
        tf = np.nanmin(np.maximum(t1, t2), axis=1)
        hit = (tn <= tf) & (tn > 0) & (tn < t_best)
        t_best[hit], ids[hit] = tn[hit], k
    keep = t_best < max_range
    return o + d[keep] * t_best[keep, None], ids[keep]


def make_frame(boxes7, types=None, beams: int = 64, **kw) -> SynthFrame:
    calib = Calibration.kitti_default()
    boxes7 = np.asarray(boxes7, dtype=float).reshape(-1, 7)
    pts, ids = scan(boxes7, calib, beams, **kw)
    lidar = calib.rect_to_lidar(pts)
    velo = np.concatenate([lidar, np.full((len(lidar), 1), 0.5)], axis=1).astype(np.float32)
    bb = project_boxes(boxes7, calib, IMAGE_SIZE, upright="lidar") if len(boxes7) else np.zeros((0, 4))
    objs = []
    for i, b in enumerate(boxes7):
        objs.append(Object3D((types or ["Car"] * len(boxes7))[i], 0.0, 0,
                             float(alpha_from_rotation_y(b[6], b[0], b[2])), bb[i],
                             b[3], b[4], b[5], b[:3], float(b[6])))
    return SynthFrame(calib, velo, ids, objs)


def write_dataset(root, frames: list[SynthFrame], split: str = "val", seed: int = 0) -> list[str]:
    """A KITTI-layout dataset of the frames: flat grey images with each car drawn as a shaded
    rectangle (so crops differ), calib, velodyne, label_2, planes, ImageSets/<split>.txt."""
    import os

    import imageio.v3 as iio

    from kitti.calib import write_calib
    from kitti.labels import write_label
    from kitti.planes import write_plane
    from kitti.splits import write_split
    from kitti.velodyne import write_velodyne

    rng = np.random.default_rng(seed)
    tr = f"{root}/training"
    ids = [f"{i:06d}" for i in range(len(frames))]
    for fid, fr in zip(ids, frames):
        img = np.full((IMAGE_SIZE[1], IMAGE_SIZE[0], 3), 110, dtype=np.uint8)
        for o in sorted(fr.objects, key=lambda o: -o.location[2]):
            x1, y1, x2, y2 = np.round(o.bbox).astype(int)
            shade = int(60 + 150 * (np.cos(o.alpha) + 1) / 2)
            img[y1:y2 + 1, x1:x2 + 1] = (shade, int(rng.integers(0, 255)), 255 - shade)
        for sub in ("image_2", "calib", "velodyne", "label_2", "planes"):
            os.makedirs(f"{tr}/{sub}", exist_ok=True)
        iio.imwrite(f"{tr}/image_2/{fid}.png", img)
        write_calib(f"{tr}/calib/{fid}.txt", fr.calib)
        write_velodyne(f"{tr}/velodyne/{fid}.bin", fr.velodyne)
        write_label(f"{tr}/label_2/{fid}.txt", fr.objects)
        write_plane(f"{tr}/planes/{fid}.txt", PLANE)
    write_split(f"{root}/ImageSets/{split}.txt", ids)
    return ids
