"""Lay a world built flat onto a road that rises and falls (`simgen.road.VerticalProfile`) and is
crowned across (`simgen.road.RoadLayout.crown`).

The scenery and the actors are placed on a flat road first (every footprint test, every lot and
stall is planned in that plan view) and then carried onto the road's surface: each static vertex
rises by the surface height under it, each actor's pose by the height under its box's bottom
centre, so a label box stands exactly on the road under it. Vehicles tilt with the road (their
wheels stay on it); people and cyclists stay upright, as they do on a slope.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import trimesh

from .facets import cross
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
    v, f = _split_edges(mesh)
    v[:, 2] += road.height(v[:, 0], v[:, 1])
    return trimesh.Trimesh(v, f, process=False)


def _split_edges(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """drape_mesh's vertices and faces before the rise: plan-view edges split to MAX_EDGE."""
    v = np.asarray(mesh.vertices) * [1.0, 1.0, _FLATTEN]
    v, f = _subdivide(v, np.asarray(mesh.faces, dtype=np.int64), MAX_EDGE)
    v[:, 2] /= _FLATTEN
    return v, f


@numba.njit(cache=True, nogil=True)
def _subdivide(v: np.ndarray, faces: np.ndarray, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """trimesh.remesh.subdivide_to_size's vertices and faces to the bit (its lengths, midpoints
    and face templates), compiled: numpy's passes over each round's faces cost a sixth of a frame.
    A face with no long edge is set aside, as trimesh keeps it, in order, ahead of every face split
    later; and midpoints are numbered in the order of their edges' (higher, lower) vertex index,
    which is how trimesh's row hash sorts them."""
    done = []
    while True:
        long, count = _long_edges(v, faces, max_edge)
        if not count.any():
            done.append(faces)
            return v, _stacked(done)
        v, mid = _midpoints(v, faces, long)
        done.append(_where_count(faces, count, 0))
        faces = _split(v, faces, long, mid, count)


@numba.njit(cache=True, nogil=True)
def _length2(v: np.ndarray, a: int, b: int) -> float:
    """Squared length of the edge from vertex a to b, summed x, y, z in turn as trimesh's
    .sum(axis=1) does."""
    dx, dy, dz = v[a, 0] - v[b, 0], v[a, 1] - v[b, 1], v[a, 2] - v[b, 2]
    return dx * dx + dy * dy + dz * dz


@numba.njit(cache=True, nogil=True)
def _long_edges(v: np.ndarray, faces: np.ndarray, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, 3) bool: whether edge e of each face (from corner e to the next) is longer than
    max_edge; and (F,) how many of each face's edges are."""
    long = np.zeros(faces.shape, np.bool_)
    count = np.zeros(faces.shape[0], np.int64)
    for i in range(faces.shape[0]):
        for e in range(3):
            if math.sqrt(_length2(v, faces[i, e], faces[i, (e + 1) % 3])) > max_edge:
                long[i, e] = True
                count[i] += 1
    return long, count


@numba.njit(cache=True, nogil=True)
def _midpoints(v: np.ndarray, faces: np.ndarray, long: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices with the long edges' midpoints appended, in the order of their edges'
    (higher, lower) vertex index, and each long edge's midpoint index (-1 where not long)."""
    n, m = v.shape[0], long.sum()
    hi, lo = np.empty(m, np.int64), np.empty(m, np.int64)
    k = 0
    for i in range(faces.shape[0]):
        for e in range(3):
            if long[i, e]:
                a, b = faces[i, e], faces[i, (e + 1) % 3]
                hi[k], lo[k] = max(a, b), min(a, b)
                k += 1
    rank, ends = np.empty(m, np.int64), np.empty((m, 2), np.int64)
    r = -1
    for k in _counting_sorted(hi, _counting_sorted(lo, np.arange(m), n), n):
        if r < 0 or hi[k] != ends[r, 0] or lo[k] != ends[r, 1]:
            r += 1
            ends[r, 0], ends[r, 1] = hi[k], lo[k]
        rank[k] = n + r
    out = np.empty((n + r + 1, 3))
    out[:n] = v
    for j in range(r + 1):
        for c in range(3):
            out[n + j, c] = (v[ends[j, 1], c] + v[ends[j, 0], c]) / 2
    mid = np.full(faces.shape, -1, np.int64)
    k = 0
    for i in range(faces.shape[0]):
        for e in range(3):
            if long[i, e]:
                mid[i, e] = rank[k]
                k += 1
    return out, mid


@numba.njit(cache=True, nogil=True)
def _counting_sorted(keys: np.ndarray, order: np.ndarray, n: int) -> np.ndarray:
    """`order` stably sorted by keys[order], keys in [0, n): a counting sort, linear in the
    edges and the vertices where a comparison sort cost most of the subdivision."""
    start = np.zeros(n + 1, np.int64)
    for k in order:
        start[keys[k] + 1] += 1
    for i in range(n):
        start[i + 1] += start[i]
    out = np.empty_like(order)
    for k in order:
        out[start[keys[k]]] = k
        start[keys[k]] += 1
    return out


@numba.njit(cache=True, nogil=True)
def _split(v: np.ndarray, faces: np.ndarray, long: np.ndarray, mid: np.ndarray,
           count: np.ndarray) -> np.ndarray:
    """The next round's faces: those with one long edge, then two, then three, each in face
    order and by trimesh's templates. One long edge, rotated to (a, b): [a, p, c] and [p, b, c].
    Two, rotated so that (c, a) is whole: all corners [p, b, q], then the quads a p q c cut along
    their shorter diagonals, as two blocks. Three: one into four."""
    tally = np.bincount(count, minlength=4)
    n1, n2, n3 = tally[1], tally[2], tally[3]
    out = np.empty((2 * n1 + 3 * n2 + 4 * n3, 3), np.int64)
    i1, i2, i3 = 0, 2 * n1, 2 * n1 + 3 * n2
    for i in range(faces.shape[0]):
        if count[i] == 1:
            j = 0 if long[i, 0] else (1 if long[i, 1] else 2)
            a, b, c, p = faces[i, j], faces[i, (j + 1) % 3], faces[i, (j + 2) % 3], mid[i, j]
            out[i1, 0], out[i1, 1], out[i1, 2] = a, p, c
            out[i1 + 1, 0], out[i1 + 1, 1], out[i1 + 1, 2] = p, b, c
            i1 += 2
        elif count[i] == 2:
            whole = 0 if not long[i, 0] else (1 if not long[i, 1] else 2)
            j = (whole + 1) % 3
            a, b, c = faces[i, j], faces[i, (j + 1) % 3], faces[i, (j + 2) % 3]
            p, q = mid[i, j], mid[i, (j + 1) % 3]
            out[i2, 0], out[i2, 1], out[i2, 2] = p, b, q
            if _length2(v, a, q) <= _length2(v, p, c):
                out[i2 + n2, 0], out[i2 + n2, 1], out[i2 + n2, 2] = a, p, q
                out[i2 + 2 * n2, 0], out[i2 + 2 * n2, 1], out[i2 + 2 * n2, 2] = a, q, c
            else:
                out[i2 + n2, 0], out[i2 + n2, 1], out[i2 + n2, 2] = a, p, c
                out[i2 + 2 * n2, 0], out[i2 + 2 * n2, 1], out[i2 + 2 * n2, 2] = p, q, c
            i2 += 1
        elif count[i] == 3:
            v0, v1, v2, m0, m1, m2 = faces[i, 0], faces[i, 1], faces[i, 2], mid[i, 0], mid[i, 1], mid[i, 2]
            out[i3, 0], out[i3, 1], out[i3, 2] = v0, m0, m2
            out[i3 + 1, 0], out[i3 + 1, 1], out[i3 + 1, 2] = m0, v1, m1
            out[i3 + 2, 0], out[i3 + 2, 1], out[i3 + 2, 2] = m2, m1, v2
            out[i3 + 3, 0], out[i3 + 3, 1], out[i3 + 3, 2] = m0, m1, m2
            i3 += 4
    return out


@numba.njit(cache=True, nogil=True)
def _where_count(faces: np.ndarray, count: np.ndarray, k: int) -> np.ndarray:
    """The faces with k long edges, in order."""
    out = np.empty((np.bincount(count, minlength=k + 1)[k], 3), np.int64)
    r = 0
    for i in range(faces.shape[0]):
        if count[i] == k:
            out[r] = faces[i]
            r += 1
    return out


@numba.njit(cache=True, nogil=True)
def _stacked(blocks: list) -> np.ndarray:
    """np.concatenate of (n, 3) blocks."""
    out = np.empty((sum([len(b) for b in blocks]), 3), np.int64)
    r = 0
    for b in blocks:
        out[r:r + len(b)] = b
        r += len(b)
    return out


def drape_parts(parts: list[Part], road: RoadLayout) -> list[Part]:
    """Static parts (world frame; anything with vertices and faces) laid onto the road as
    drape_mesh lays each, as trimeshes; unchanged on a flat road."""
    if road.flat:
        return parts
    split = [_split_edges(p.mesh) for p in parts]
    v = np.concatenate([v for v, _ in split])  # every part's rise in one call: it is elementwise
    rise = np.split(road.height(v[:, 0], v[:, 1]), np.cumsum([len(v) for v, _ in split])[:-1])
    for (v, _), z in zip(split, rise):
        v[:, 2] += z
    return [Part(trimesh.Trimesh(v, f, process=False), p.material) for p, (v, f) in zip(parts, split)]


def _tilt_to(normal: np.ndarray) -> np.ndarray:
    """The smallest rotation taking world up (0, 0, 1) to `normal` (Rodrigues)."""
    axis = cross([0.0, 0.0, 1.0], normal)
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
    z, n = road.surface(x, y)
    pose = actor.pose.copy()
    pose[2, 3] += z
    if actor.cls in TILTED:
        pose[:3, :3] = _tilt_to(n) @ pose[:3, :3]
    actor.pose = pose
    v = np.asarray(actor.velocity, dtype=float).copy()
    v[2] = -(n[0] * v[0] + n[1] * v[1]) / n[2]
    actor.velocity = v
