"""KITTI formats, frames, box geometry, exact IoU and the official evaluation.

Depends on numpy, numba (exact IoU and the evaluation's loops), imageio (images) and tqdm
(progress bars), never on the simulator or torch, so it serves real KITTI data as well as the
testbed's own.
"""

from .boxes import (alpha_from_rotation_y, box_corners, lidar_upright_corners, points_in_boxes,
                    project_boxes, rotation_y_from_alpha)
from .calib import Calibration, read_calib, write_calib
from .dataset import KittiDataset
from .drives import read_drives
from .errors import KittiFormatError
from .iou import iou_2d, iou_3d, iou_bev
from .labels import Object3D, boxes7, read_label, write_label
from .planes import read_plane, write_plane
from .splits import read_split, write_split
from .velodyne import read_velodyne, write_velodyne

__all__ = [
    "Calibration", "KittiDataset", "KittiFormatError", "Object3D", "alpha_from_rotation_y",
    "box_corners", "boxes7", "iou_2d", "iou_3d", "iou_bev", "lidar_upright_corners",
    "points_in_boxes", "project_boxes", "read_calib", "read_drives", "read_label", "read_plane",
    "read_split", "read_velodyne", "rotation_y_from_alpha", "write_calib", "write_label", "write_plane",
    "write_split", "write_velodyne",
]
