"""The world as one Embree triangle scene, with per-triangle actor id and material.

Rays hit the very meshes the camera renders (every actor part and static part), not proxy
shapes. All triangles go into a single Embree geometry, so a hit's primID indexes the
lookup arrays directly. Per triangle: the material's reflectivity and incidence exponent (the
scan's hot path gathers those), and an index into the world's distinct materials, whose
porosity and transmittance the pass-through step reads for the few hits that need them.

Motion: Embree in embreex has no motion blur, so each moving actor is placed once, at its
pose at the instant the head sweeps across the actor's centre bearing (`placed_time`);
`scan` then moves each hit on it along the facet normal by the actor's rigid motion between
that instant and the ray's own time. For an actor seen by a 10 Hz head the beam crosses it
within a few milliseconds of the placement, so the error is second order (a car 4 m wide at
10 m spans 23 deg = 6 ms: at 15 m/s its edges are placed 5 cm off before the correction).
An actor straddling the back, where a sweep starts and ends 0.1 s apart, is seen at both
ends; its hits are shifted likewise, but its silhouette there may be off by up to v x 0.1 s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from embreex.rtcore_scene import EmbreeScene

from ..embree import embree_scene
from ..world import World
from .kernels import triangle_planes
from .rays import sweep_time_of_azimuth
from .spec import LidarSpec
from .windows import Windows, windows_of


@dataclass
class Target:
    scene: EmbreeScene
    tri_actor: np.ndarray  # (F,) int32 actor id per triangle, 0 = static
    tri_slot: np.ndarray  # (F,) int32 index into the per-actor arrays below, -1 = static
    tri_refl: np.ndarray  # (F,) float32 LiDAR reflectivity per triangle (Material.reflectivity)
    tri_expo: np.ndarray  # (F,) float32 Material.incidence_exponent per triangle
    tri_mat: np.ndarray  # (F,) int16 index into `materials`
    tri_passes: np.ndarray  # (F,) bool: a porous or glass triangle (rays may pass on)
    materials: tuple  # the distinct simgen.world.Material objects, in first-seen order
    mat_porosity: np.ndarray  # (M,) float32
    mat_transmittance: np.ndarray  # (M,) float32
    # Glass parts are closed convex solids (a car's glasshouse, a window box): where a ray that
    # entered one leaves it follows from its face planes (kernels.pass_prepare), with no query.
    tri_glass: np.ndarray  # (F,) int32 index into glass_planes, -1 = not glass
    glass_planes: np.ndarray  # (G, K, 4) float32 outward unit normal and offset per face, zero-padded
    tri_inv_ng: np.ndarray  # (F,) float32 1 / |edge cross product|: normalises Embree's Ng
    tri_plane: np.ndarray  # (F, 4) float64 edge cross product n and n . vertex (kernels.exact_hits)
    windows: Windows  # the façades' windows (static triangles come first)
    actor_ids: np.ndarray  # (A,) int32
    placed_time: np.ndarray  # (A,) float64 time each actor's mesh is placed at
    placed_origin: np.ndarray  # (A, 3) actor origin (world) at placed_time
    velocity: np.ndarray  # (A, 3)
    yaw_rate: np.ndarray  # (A,)
    n_triangles: int
    first_actor: int  # the static world's triangles come first: primID < first_actor
    first_moving: int  # moving actors' triangles come last: primID >= first_moving


def placement_times(world: World, spec: LidarSpec, iterations: int = 3) -> np.ndarray:
    """Per actor, the time the head faces its centre; a fixed point of t -> bearing(t)."""
    t = np.zeros(len(world.actors))
    if not spec.motion:
        return t
    r_inv = world.lidar_pose[:3, :3].T
    for i, a in enumerate(world.actors):
        if not (np.any(np.asarray(a.velocity) != 0) or a.yaw_rate != 0):
            continue  # a still actor is the same at every time
        v = np.concatenate([_arr(p.mesh.vertices) for p in a.parts])
        centre = np.append(0.5 * (v.min(axis=0) + v.max(axis=0)), 1.0)  # actor frame
        for _ in range(iterations):
            p = r_inv @ ((a.pose_at(t[i]) @ centre)[:3] - world.lidar_pose_at(t[i])[:3, 3])
            t[i] = np.clip(sweep_time_of_azimuth(np.arctan2(p[1], p[0]), spec),
                           -spec.period / 2, spec.period / 2)
    return t


def _arr(a) -> np.ndarray:
    """A plain ndarray view of a trimesh TrackedArray (skips its per-access hashing); a plain
    ndarray (a PartMesh's) as it is."""
    return a if type(a) is np.ndarray else np.asarray(a).view(np.ndarray)


def _glass_planes(v_all: np.ndarray, f_all: np.ndarray, panes: list[tuple[int, int, int, int]],
                  n_tri: int) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle, its glass part (-1: none); per glass part (a closed convex mesh), its faces'
    outward unit normals and offsets (n . p = offset), oriented away from the part's vertex
    centroid whatever the winding, zero-padded to (G, K, 4). All parts in one vectorised pass."""
    tri_glass = np.full(n_tri, -1, np.int32)
    if not panes:
        return tri_glass, np.zeros((0, 0, 4), np.float32)
    f0, nf, v0, nvp = (np.array(c, np.int64) for c in zip(*panes))
    part = np.repeat(np.arange(len(panes)), nf)
    tris = np.concatenate([np.arange(a, a + b) for a, b in zip(f0, nf)])
    tri_glass[tris] = part
    centroid = np.add.reduceat(v_all[np.concatenate([np.arange(a, a + b) for a, b in zip(v0, nvp)])],
                               np.concatenate([[0], np.cumsum(nvp)[:-1]])) / nvp[:, None]
    t = v_all[f_all[tris]].astype(np.float64)
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    off = np.einsum("ij,ij->i", n, t[:, 0])
    flip = np.einsum("ij,ij->i", n, centroid[part]) > off  # the centroid must lie behind each face
    n[flip], off[flip] = -n[flip], -off[flip]
    planes = np.zeros((len(panes), int(nf.max()), 4), np.float32)
    planes[part, tris - np.repeat(f0, nf)] = np.concatenate([n, off[:, None]], axis=1)
    return tri_glass, planes


def _embree_scene(verts: list, faces: list):
    """One Embree scene of every triangle (BVH built now), the concatenated vertices and faces,
    each triangle's plane (kernels.exact_hits) and inverse doubled area (for barycentric work
    in the kernels)."""
    if not verts:
        return EmbreeScene(), None, None, np.zeros((0, 4)), np.zeros(0, np.float32)
    v_all = np.ascontiguousarray(np.concatenate(verts), dtype=np.float32)
    f_all = np.ascontiguousarray(np.concatenate(faces), dtype=np.int32)
    scene = embree_scene(v_all, f_all)
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))  # build the BVH now
    return scene, v_all, f_all, *triangle_planes(v_all, f_all)


def _placed(verts: list, poses: list, pose_of: list) -> list:
    """Each part's vertices `verts[k]` moved by `poses[pose_of[k]]` (None: left as they are).
    Parts of one vertex count go through one stacked product: numpy's matmul runs the same BLAS
    product per stacked matrix as for one part alone, so the bits are the per-part product's."""
    out = list(verts)
    by_size: dict = {}
    for k, j in enumerate(pose_of):
        if j is not None:
            by_size.setdefault(len(verts[k]), []).append(k)
    for ks in by_size.values():
        m = np.stack([poses[pose_of[k]] for k in ks])
        moved = np.stack([verts[k] for k in ks]) @ m[:, :3, :3].transpose(0, 2, 1) + m[:, None, :3, 3]
        for k, v in zip(ks, moved):
            out[k] = v
    return out


def build_target(world: World, spec: LidarSpec) -> Target:
    """Concatenate every triangle in world frame (actors at their placement poses): static
    parts, then still actors, then moving actors, so one comparison finds hits to correct."""
    t_place = placement_times(world, spec)
    parts = list(world.static)
    actor, slot, pose_of = [0] * len(parts), [-1] * len(parts), [None] * len(parts)
    poses = []
    placed_origin = np.zeros((len(world.actors), 3))
    moves = [spec.motion and (bool(np.any(np.asarray(a.velocity) != 0)) or a.yaw_rate != 0)
             for a in world.actors]
    n_still = 0
    for moving in (False, True):
        if moving:
            n_still = len(parts)
        for i, (a, t) in enumerate(zip(world.actors, t_place)):
            if moves[i] != moving:
                continue
            pose = a.pose_at(float(t))
            placed_origin[i] = pose[:3, 3]
            parts += a.parts
            actor += [a.id] * len(a.parts)
            slot += [i] * len(a.parts)
            pose_of += [len(poses)] * len(a.parts)
            poses.append(pose)

    # Per part: its vertices and faces; its actor, slot and material once, expanded to its
    # triangles below (one np.repeat each, not one np.full per part).
    verts = _placed([_arr(p.mesh.vertices) for p in parts], poses, pose_of)
    faces = [_arr(p.mesh.faces) for p in parts]
    counts = [len(f) for f in faces]
    first_moving = sum(counts[:n_still])
    nvs = [len(v) for v in verts]
    if faces:  # each part's faces offset to index the concatenated vertices, in one pass
        faces = [np.concatenate(faces) + np.repeat(np.cumsum([0, *nvs[:-1]]), counts)[:, None]]
    mats: dict = {}
    mat = [mats.setdefault(p.material, len(mats)) for p in parts]
    f0, v0 = np.cumsum([0, *counts]), np.cumsum([0, *nvs])
    panes = [(int(f0[k]), counts[k], int(v0[k]), nvs[k]) for k, p in enumerate(parts)
             if p.material.transmittance > 0]  # glass parts: first triangle, count, first vertex, count

    scene, v_all, f_all, plane, inv_ng = _embree_scene(verts, faces)
    cat = (lambda xs, dt: np.repeat(np.array(xs, dt), counts))
    materials = tuple(mats)
    table = (lambda f: np.array([f(m) for m in materials], np.float32).reshape(-1))
    tri_mat = cat(mat, np.int16)
    tri_glass, glass_planes = (_glass_planes(v_all, f_all, panes, len(tri_mat)) if verts
                               else (np.zeros(0, np.int32), np.zeros((0, 0, 4), np.float32)))
    mat_porosity, mat_transmittance = table(lambda m: m.porosity), table(lambda m: m.transmittance)
    return Target(
        scene=scene,
        tri_actor=cat(actor, np.int32),
        tri_slot=cat(slot, np.int32),
        tri_refl=table(lambda m: m.reflectivity)[tri_mat],
        tri_expo=table(lambda m: m.incidence_exponent)[tri_mat],
        tri_mat=tri_mat,
        tri_passes=((mat_porosity > 0) | (mat_transmittance > 0))[tri_mat],
        materials=materials,
        mat_porosity=mat_porosity,
        mat_transmittance=mat_transmittance,
        tri_glass=tri_glass,
        glass_planes=glass_planes,
        tri_inv_ng=inv_ng,
        tri_plane=plane,
        windows=windows_of(world, sum(counts)),
        actor_ids=np.array([a.id for a in world.actors], dtype=np.int32),
        placed_time=t_place,
        placed_origin=placed_origin,
        velocity=np.array([np.asarray(a.velocity, float) for a in world.actors]).reshape(-1, 3),
        yaw_rate=np.array([float(a.yaw_rate) for a in world.actors]),
        n_triangles=sum(counts),
        first_actor=sum(counts[:len(world.static)]),
        first_moving=first_moving,
    )


class TargetCache:
    """The targets of one world for several sensors. build_target reads two things of a spec,
    whether the sweep models motion and how fast the head turns (they place the moving actors),
    so sensors that agree on them (every preset: 10 Hz, with motion) share one Embree scene."""

    def __init__(self, world: World):
        self.world = world
        self._built: dict[tuple[bool, float], Target] = {}

    def get(self, spec: LidarSpec) -> Target:
        key = (spec.motion, spec.rotation_hz)
        if key not in self._built:
            self._built[key] = build_target(self.world, spec)
        return self._built[key]
