"""A self-contained KITTI-like street for the LiDAR tests and benchmark.

Used where the scene generator's sampled worlds are not wanted (unit tests need a world that
does not change when the scene code does) or not yet available. It is built from the same
Part/Actor/World types and actor meshes as the generated worlds: a road with raised
sidewalks, building blocks on both sides with gaps and a cross street, trees and poles,
parked cars along both curbs and moving cars in the lanes.
"""

from __future__ import annotations

import numpy as np
import trimesh

from simgen.meshes import build_actor_parts, sample_recipe
from simgen.world import Actor, Material, Part, Weather, World

ASPHALT = Material("asphalt", (0.08, 0.08, 0.08), 0.12)
SIDEWALK = Material("concrete", (0.35, 0.35, 0.33), 0.30)
FACADE = Material("facade", (0.50, 0.45, 0.40), 0.35)
FOLIAGE = Material("foliage", (0.05, 0.20, 0.05), 0.55)  # leaves are bright at 905 nm
BARK = Material("bark", (0.15, 0.10, 0.05), 0.25)
METAL = Material("pole", (0.40, 0.40, 0.40), 0.40)


def _box(x0, x1, y0, y1, z0, z1) -> trimesh.Trimesh:
    return trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, z1]])


def _pose(x: float, y: float, yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def street_world(seed: int = 0, half_width: float = 7.5, moving_cars: int = 4,
                 parked_per_side: int = 6, weather: Weather | None = None) -> World:
    """Ego at the origin on a straight street along +x, LiDAR 1.73 m above the road."""
    rng = np.random.default_rng(seed)
    static = [Part(_box(-150, 150, -half_width, half_width, -0.1, 0.0), ASPHALT)]
    sw = 3.0
    for s in (-1, 1):
        y0, y1 = sorted((s * half_width, s * (half_width + sw)))
        static.append(Part(_box(-150, 150, y0, y1, -0.1, 0.15), SIDEWALK))
        x = -150.0
        while x < 150.0:
            length = rng.uniform(12, 35)
            if 25 < x + length / 2 < 45:  # the cross street stays open
                x += length
                continue
            depth = rng.uniform(10, 20)
            height = rng.uniform(6, 25)
            yb = s * (half_width + sw)
            ya, yb2 = sorted((yb, yb + s * depth))
            static.append(Part(_box(x, x + length, ya, yb2, 0.0, height), FACADE))
            x += length + rng.uniform(0, 6)
        for tx in np.arange(-60, 80, rng.uniform(12, 18)):
            ty = s * (half_width + 1.2)
            trunk = trimesh.creation.cylinder(radius=0.15, height=2.5, sections=10)
            trunk.apply_translation([tx, ty, 1.25 + 0.15])
            crown = trimesh.creation.icosphere(subdivisions=2, radius=rng.uniform(1.2, 2.0))
            crown.apply_translation([tx, ty, 4.2])
            static += [Part(trunk, BARK), Part(crown, FOLIAGE)]
        for px in np.arange(-50, 70, 25.0):
            pole = trimesh.creation.cylinder(radius=0.08, height=6.0, sections=8)
            pole.apply_translation([px + 5, s * (half_width + 0.4), 3.15])
            static.append(Part(pole, METAL))

    actors: list[Actor] = []
    aid = 1
    for s in (-1, 1):
        for x in np.sort(rng.uniform(-40, 60, parked_per_side)):
            recipe = sample_recipe("Car", rng)
            actors.append(Actor(aid, "Car", build_actor_parts(recipe),
                                _pose(float(x), s * (half_width - 1.1), 0.0 if s < 0 else np.pi)))
            aid += 1
    for i in range(moving_cars):
        lane = -1 if i % 2 == 0 else 1
        x = float(rng.uniform(8, 50)) * (1 if i < moving_cars // 2 + 1 else -0.6)
        speed = float(rng.uniform(5, 14))
        yaw = 0.0 if lane > 0 else np.pi
        recipe = sample_recipe("Car", rng)
        actors.append(Actor(aid, "Car", build_actor_parts(recipe),
                            _pose(x, lane * half_width / 2.6, yaw),
                            velocity=np.array([speed * np.cos(yaw), 0.0, 0.0])))
        aid += 1
    lidar = np.eye(4)
    lidar[2, 3] = 1.73
    return World(actors=actors, static=static, weather=weather or Weather(), lidar_pose=lidar,
                 ego_velocity=np.array([8.0, 0.0, 0.0]))
