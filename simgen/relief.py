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
    v, f = _subdivide(v, np.asarray(mesh.faces, dtype=np.int64), MAX_EDGE)
    v[:, 2] /= _FLATTEN
    v[:, 2] += road.height(v[:, 0], v[:, 1])
    return trimesh.Trimesh(v, f, process=False)


def _subdivide(v: np.ndarray, faces: np.ndarray, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """trimesh.remesh.subdivide_to_size's vertices and faces to the bit (its lengths, midpoints
    and face templates), at a third of the cost: a face with no long edge is set aside, as trimesh
    keeps it, in order, ahead of every face split later; and midpoints are numbered in the order
    of their edges' (higher, lower) vertex index, which is how trimesh's row hash sorts them."""
    done = []
    while True:
        nxt = faces[:, [1, 2, 0]]
        long = _length2(v, faces, nxt) ** 0.5 > max_edge
        if not long.any():
            return v, np.concatenate(done + [faces])
        n = len(v)
        a, b = np.compress(long.ravel(), faces), np.compress(long.ravel(), nxt)
        ends, inverse = np.unique(np.maximum(a, b) * n + np.minimum(a, b), return_inverse=True)
        v = np.concatenate([v, (np.take(v, ends % n, axis=0) + np.take(v, ends // n, axis=0)) / 2])
        mid = np.full(long.shape, -1, np.int64)
        mid[long] = n + inverse
        count = long.sum(axis=1)
        done.append(np.compress(count == 0, faces, axis=0))
        # One long edge, rotated to (a, b): [a, p, c] and [p, b, c].
        f, m, split = _rows(count == 1, faces, mid, long)
        j, r = np.argmax(split, axis=1), np.arange(len(f))
        a, b, c, p = f[r, j], f[r, (j + 1) % 3], f[r, (j + 2) % 3], m[r, j]
        one = np.column_stack((a, p, c, p, b, c)).reshape((-1, 3))
        # Two, rotated so that (c, a) is whole: the corner [p, b, q], and the quad a p q c cut
        # along its shorter diagonal.
        f, m, split = _rows(count == 2, faces, mid, long)
        j, r = (np.argmin(split, axis=1) + 1) % 3, np.arange(len(f))
        a, b, c = f[r, j], f[r, (j + 1) % 3], f[r, (j + 2) % 3]
        p, q = m[r, j], m[r, (j + 1) % 3]
        aq = (_length2(v, a, q) <= _length2(v, p, c))[:, None]
        two = np.concatenate([np.column_stack((p, b, q)),
                              np.where(aq, np.column_stack((a, p, q)), np.column_stack((a, p, c))),
                              np.where(aq, np.column_stack((a, q, c)), np.column_stack((p, q, c)))])
        # Three: one into four.
        (v0, v1, v2), (m0, m1, m2) = (x.T for x in _rows(count == 3, faces, mid))
        three = np.column_stack((v0, m0, m2, m0, v1, m1, m2, m1, v2, m0, m1, m2)).reshape((-1, 3))
        faces = np.concatenate([one, two, three])


def _rows(where: np.ndarray, *arrays: np.ndarray) -> list[np.ndarray]:
    """Each array's rows where `where` holds (np.compress: a few times faster than a boolean index)."""
    return [np.compress(where, x, axis=0) for x in arrays]


def _length2(v: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared lengths of the edges from vertices a to b, summed x, y, z in turn as trimesh's
    .sum(axis=1) does; a coordinate at a time, as numpy gathers and adds rows of 3 several times
    slower."""
    total = 0.0
    for x in v.T:
        d = np.take(x, a) - np.take(x, b)
        total = total + d * d
    return total


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
