"""The gantry rig of 004: the camera's height, pan and tilt fix the road plane in the camera frame
(planes/ gives it as a·x + b·y + c·z + d = 0 in rect coordinates: d is the height, the normal the
tilt and roll), and an object stands on the road (its box upright on the road, not on the tilted
camera's x-z plane; vehicles touch it with their tyres, see `mono`).

The 2D box's bottom-centre ray meets the road at the object's nearest visible bottom point; the
box of the predicted size and orientation is then placed on the road so that its projection fits
the 2D box (the 003 constraints plus the road row, solved together by least squares), which is
the projected-corner form of the same back-projection and holds for any pan and tilt.
"""

from __future__ import annotations

import numpy as np

from kitti.boxes import wrap_angle
from kitti.calib import Calibration

from .mono import box_up_of, contact_of, ground_point, solve_from_alpha
from .road import FixedRoad, LocalRoad, plane_under
from .types import Box2D, Lifted, Prior


def lift_roadside(boxes: list[Box2D], priors: list[Prior], calib: Calibration,
                  image_size: tuple[int, int], road: LocalRoad | FixedRoad | np.ndarray,
                  outline: str = "silhouette", cam: int = 2) -> list[Lifted]:
    """`road`: a plane (a, b, c, d; rect frame) or a road model (the plane under each box)."""
    road = FixedRoad(road) if isinstance(road, np.ndarray) else road
    out = []
    for box, prior in zip(boxes, priors):
        dims = np.asarray(prior.dims, dtype=float)
        plane = plane_under(road, box.centre[0], box.bbox[3], calib.P(cam))
        try:
            sol = solve_from_alpha(dims, prior.alpha, box.bbox, calib, image_size, plane, cam,
                                   contact=contact_of(box.type, outline),
                                   box_up=box_up_of(outline, calib))
            out.append(Lifted(sol.location, sol.rotation_y, dims))
        except ValueError:  # cut by the border on three sides: the bottom-centre ray alone
            g = ground_point(box.centre[0], box.bbox[3], calib, plane, cam)
            ray = g[[0, 2]] / np.linalg.norm(g[[0, 2]])
            g[[0, 2]] += ray * min(dims[1], dims[2]) / 2  # the centre lies beyond the near face
            ry = float(wrap_angle(prior.alpha + np.arctan2(g[0], g[2])))
            out.append(Lifted(g, ry, dims, quality=0.5))
    return out
