"""Small worlds built by hand for the scene-generator tests."""

from __future__ import annotations

import numpy as np

from simgen.meshes import build_actor_parts
from simgen.rigs import onboard_rig
from simgen.world import Actor, Light, Weather, World

CAR = {"kind": "car", "dims": [1.53, 1.63, 3.88], "color": [0.55, 0.04, 0.03], "seed": 7}


def pose(x: float, y: float, yaw: float = 0.0, z: float = 0.0) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [x, y, z]
    return T


def world_of(placements: list[tuple[dict, np.ndarray]], cls: str = "Car") -> World:
    """Actors (recipe, pose) on the KITTI onboard rig, no static scenery, plain daylight."""
    rig = onboard_rig()
    actors = [Actor(i + 1, cls, build_actor_parts(r), p, recipe=r) for i, (r, p) in enumerate(placements)]
    return World(actors=actors, static=[], weather=Weather(), lidar_pose=rig.reference_pose.copy(),
                 rig=rig, light=Light())


def mask_box(instance: np.ndarray, actor_id: int) -> np.ndarray:
    ys, xs = np.nonzero(instance == actor_id)
    return np.array([xs.min(), ys.min(), xs.max(), ys.max()], float)
