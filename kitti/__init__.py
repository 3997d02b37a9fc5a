"""KITTI formats, frames, box geometry, exact IoU and the official evaluation.

Depends on numpy, numba (exact IoU and the evaluation's loops), imageio (images) and tqdm
(progress bars), never on the simulator or torch, so it serves real KITTI data as well as the
testbed's own.
"""

from importlib import import_module

from .cpu import pin

pin()  # before numpy loads: the same kernels, hence the same bytes, on every covered CPU

# The public names, each loaded from its module at first use, so `import kitti` (which every
# package does first, for the pins) costs nothing until a name is used: `testbed --help` loads
# no numpy.
_MODULE_OF = {
    "alpha_from_rotation_y": "boxes", "box_corners": "boxes", "lidar_upright_corners": "boxes",
    "points_in_boxes": "boxes", "project_boxes": "boxes", "rotation_y_from_alpha": "boxes",
    "Calibration": "calib", "read_calib": "calib", "write_calib": "calib",
    "KittiDataset": "dataset", "read_drives": "drives", "KittiFormatError": "errors",
    "iou_2d": "iou", "iou_3d": "iou", "iou_bev": "iou",
    "Object3D": "labels", "boxes7": "labels", "read_label": "labels", "write_label": "labels",
    "read_plane": "planes", "write_plane": "planes", "read_split": "splits", "write_split": "splits",
    "read_velodyne": "velodyne", "write_velodyne": "velodyne",
}
__all__ = sorted(_MODULE_OF)


def __getattr__(name: str):
    if name not in _MODULE_OF:
        raise AttributeError(f"module 'kitti' has no attribute {name!r}")
    value = getattr(import_module(f".{_MODULE_OF[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
