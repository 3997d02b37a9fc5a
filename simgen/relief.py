"""Lay a world built flat onto a road that rises and falls (`simgen.road.VerticalProfile`) and is
crowned across (`simgen.road.RoadLayout.crown`).

The scenery and the actors are placed on a flat road first (every footprint test, every lot and
stall is planned in that plan view) and then carried onto the road's surface: each static vertex
rises by the surface height under it, each actor's pose by the height under its box's bottom
centre, so a label box stands exactly on the road under it. Vehicles tilt with the road (their
wheels stay on it); people and cyclists stay upright, as they do on a slope.
"""

from __future__ import annotations

import numpy as np
import trimesh

from .road import RoadLayout
from .world import Actor, Part

# Longest plan-view edge a draped mesh keeps: the surface is a parabola between vertices, and a
# chord of length e departs from it by at most |dg/ds| e^2 / 8 = e^2 / (800 K): 4.5 mm at K = 10
# m/%, under the 1 cm that lane paint stands above the asphalt (simgen.scenery.MARK_Z). It
# triples a street's static triangles (median 18k flat, 59k draped, scenes/urban.yaml frames 0-5).
# The crown is linear across each half of the carriageway, which meets the other at the divider
# (`simgen.scenery._carriageway`), and flat beyond the curbs: splitting adds no error there.
MAX_EDGE = 6.0
TILTED = frozenset({"Car", "Van", "Truck", "Tram", "Bus"})
_FLATTEN = 1.0 / 1024.0  # exact in binary: squeezes heights so only plan-view edges are split


def drape_mesh(mesh: trimesh.Trimesh, road: RoadLayout) -> trimesh.Trimesh:
    """The mesh with plan-view edges split to MAX_EDGE and every vertex raised by the road's
    height under it. Splitting puts new vertices at edge midpoints, so the squeezed heights
    scale back exactly and vertical walls are split only along their length."""
    v = np.asarray(mesh.vertices) * [1.0, 1.0, _FLATTEN]
    v, f = trimesh.remesh.subdivide_to_size(v, np.asarray(mesh.faces), max_edge=MAX_EDGE)
    v[:, 2] /= _FLATTEN
    v[:, 2] += road.height(v[:, 0], v[:, 1])
    return trimesh.Trimesh(v, f, process=False)


def drape_parts(parts: list[Part], road: RoadLayout) -> list[Part]:
    """Static parts (world frame) laid onto the road; unchanged on a flat road."""
    if road.flat:
        return parts
    return [Part(drape_mesh(p.mesh, road), p.material) for p in parts]


def _tilt_to(normal: np.ndarray) -> np.ndarray:
    """The smallest rotation taking world up (0, 0, 1) to `normal` (Rodrigues)."""
    axis = np.cross([0.0, 0.0, 1.0], normal)
    s, c = np.linalg.norm(axis), normal[2]
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * K @ K


def drape_actor(actor: Actor, road: RoadLayout) -> None:
    """Raise the actor onto the road under its origin (its box's bottom centre) and let it move
    along the surface there (its velocity gains the climb); vehicles also tilt to the surface."""
    if road.flat:
        return
    x, y = actor.pose[0, 3], actor.pose[1, 3]
    n = road.surface_normal(x, y)
    pose = actor.pose.copy()
    pose[2, 3] += float(road.height(x, y))
    if actor.cls in TILTED:
        pose[:3, :3] = _tilt_to(n) @ pose[:3, :3]
    actor.pose = pose
    v = np.asarray(actor.velocity, dtype=float).copy()
    v[2] = -(n[0] * v[0] + n[1] * v[1]) / n[2]
    actor.velocity = v
