"""The thesis's lifting (000, Algorithm "3D vehicle detection exploiting 2D detection results with
LiDAR point clouds"), step by step. Where the thesis gives no number, the number chosen is named here.

1. ground removal by height above the road assumed from the LiDAR mounting height;
2. LiDAR returns projected into image_2 and kept inside each 2D box, with their depth;
3. surface point: the nearest return on the vertical line through the 2D box centre; the box's
   returns are clustered by depth gaps and the closest return of the surface point's cluster kept;
4. pose from the predicted size and orientation, depth offset from the surface to the centre
   (Table 5.1), centre depth t_z = l_z + |offset|;
5. occlusion: boxes sorted by their closest return; a car whose centre line hits a car in front
   gets t_z = t_z(front) + (closest - closest(front)) (the printed formula has this gap reversed);
6. (u, v, t_z) back-projected through the calibration; KITTI's location is the bottom centre,
   h/2 below the geometric centre.
"""

from __future__ import annotations

import numpy as np

from kitti.boxes import wrap_angle
from kitti.calib import Calibration

from .points import FramePoints
from .types import Box2D, Lifted, Prior

# Numbers the thesis does not give (chosen here):
LIDAR_HEIGHT = 1.73   # m, the KITTI rig's LiDAR above the road (the thesis: "LiDAR height")
GROUND_CUT = 0.25     # m, returns lower than this above the assumed road are ground
DEPTH_GAP = 1.0       # m, a gap in depth larger than this starts a new cluster
CENTRE_COL_PX = 2.0   # px, half-width of the "vertical line through the 2D centre" (azimuth step
CENTRE_COL_FRAC = 0.03  # of KITTI's HDL-64 is ~2.3 px), widened to 3 % of the box width


def thesis_depth_offset(alpha: float, w: float, l: float) -> tuple[str, float]:
    """Pose and |depth offset| from the surface point to the centre (Table 5.1).

    alpha is the angle between the viewing ray and the car's lateral axis, so the ray through the
    centre leaves the car through a long side at (w/2)/|cos alpha| and through the front or back
    at (l/2)/|sin alpha|; it is the side that is seen when the first is the shorter,
    i.e. |tan alpha| < l/w. The four rows of Table 5.1 are the four quadrants of alpha; the
    thesis takes the absolute value (Eq. 5.4).
    """
    c, s = abs(np.cos(alpha)), abs(np.sin(alpha))
    if s * w < c * l:
        return "side", w / (2 * c)
    return "front/back", l / (2 * s)


def _clusters(depths: np.ndarray) -> np.ndarray:
    """Cluster label per return from gaps in sorted depth."""
    order = np.argsort(depths, kind="stable")
    gaps = np.diff(depths[order]) > DEPTH_GAP
    labels = np.empty(len(depths), dtype=int)
    labels[order] = np.concatenate([[0], np.cumsum(gaps)])
    return labels


def lift_frustum(boxes: list[Box2D], priors: list[Prior], pts: FramePoints,
                 calib: Calibration, cam: int = 2) -> list[Lifted | None]:
    """One Lifted per box, None where the box holds no non-ground return (the thesis has no answer
    there; the caller falls back to the image-only lifting)."""
    depth = pts.rect[:, 2]
    height = pts.sensor[1] + LIDAR_HEIGHT - pts.rect[:, 1]  # above the assumed road, rect y is down
    above = height > GROUND_CUT
    n = len(boxes)
    idx: list[np.ndarray] = []
    surface = np.full(n, -1)
    closest = np.full(n, np.inf)
    members: list[np.ndarray] = []
    for i, box in enumerate(boxes):
        inside = pts.in_box(box.bbox)
        inside = inside[above[inside]]
        idx.append(inside)
        members.append(inside[:0])
        if len(inside) == 0:
            continue
        tx = box.centre[0]
        half = max(CENTRE_COL_PX, CENTRE_COL_FRAC * (box.bbox[2] - box.bbox[0]))
        line = inside[np.abs(pts.uv[inside, 0] - tx) <= half]
        if len(line) == 0:  # sparse scan: the returns nearest the centre column stand in for it
            du = np.abs(pts.uv[inside, 0] - tx)
            line = inside[du <= du.min() + 1e-9]
        surface[i] = line[np.argmin(depth[line])]
        labels = _clusters(depth[inside])
        members[i] = inside[labels == labels[np.flatnonzero(inside == surface[i])[0]]]
        closest[i] = depth[members[i]].min()

    y2 = np.array([b.bbox[3] for b in boxes])
    order = sorted((i for i in range(n) if surface[i] >= 0), key=lambda i: (closest[i], -y2[i]))
    owner = np.full(len(depth), -1)
    c_depth = np.full(n, np.nan)
    out: list[Lifted | None] = [None] * n
    for i in order:
        front = owner[surface[i]]
        if front >= 0:  # the centre line hits a car in front: the occlusion rule
            own = idx[i][owner[idx[i]] < 0]
            if len(own) == 0:
                continue
            labels = _clusters(depth[own])
            near = labels[np.argmin(depth[own])]
            members[i] = own[labels == near]
            closest[i] = depth[members[i]].min()
            c_depth[i] = c_depth[front] + (closest[i] - closest[front])
        else:
            _, offset = thesis_depth_offset(priors[i].alpha, priors[i].dims[1], priors[i].dims[2])
            c_depth[i] = depth[surface[i]] + abs(offset)
        owner[members[i][owner[members[i]] < 0]] = i
        tx, ty = boxes[i].centre
        centre = calib.image_to_rect(np.array([[tx, ty]]), np.array([c_depth[i]]), cam)[0]
        h = float(priors[i].dims[0])
        loc = centre + np.array([0.0, h / 2, 0.0])
        ry = float(wrap_angle(priors[i].alpha + np.arctan2(loc[0], loc[2])))
        out[i] = Lifted(loc, ry, np.asarray(priors[i].dims, dtype=float))
    return out
