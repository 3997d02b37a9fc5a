"""The lifter's small typed inputs and outputs."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# px, how far a labelled 2D box's left and right sides lie from the lifter's box projected: the
# body's outline lies 1-3 px inside the box's corners on the testbed's cars. A detected box's
# sides carry their detector's errors besides (lifter.pipeline.SHIPPED_SIDE_ERRORS).
LABEL_SIDE_SIGMA_PX = 2.0


@dataclass
class Box2D:
    """A 2D box to lift: from the labels (oracle) or from a detection file."""

    type: str
    bbox: np.ndarray  # (4,) x1, y1, x2, y2 in image_2 pixels
    score: float
    side_sigma: float = LABEL_SIDE_SIGMA_PX  # px, the scale of its left and right sides' errors
    side_dof: float = math.inf  # their Student-t degrees of freedom (inf: Gaussian; `placement.side_cost`)

    @property
    def centre(self) -> tuple[float, float]:
        return 0.5 * (self.bbox[0] + self.bbox[2]), 0.5 * (self.bbox[1] + self.bbox[3])


@dataclass
class Prior:
    """Size and local orientation of one box, from the network (or the truth in tests)."""

    dims: np.ndarray  # (3,) h, w, l metres
    alpha: float


@dataclass
class Lifted:
    """A 3D box for one 2D box: bottom-face centre, yaw, size, and a quality in (0, 1]."""

    location: np.ndarray  # (3,) rect frame, bottom-face centre
    rotation_y: float
    dims: np.ndarray      # (3,) h, w, l
    quality: float = 1.0
