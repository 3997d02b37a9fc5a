"""Sun shadows for the camera, cast by the very meshes the LiDAR sees (Embree ray casting).

For every visible surface point (back-projected from the depth image) one ray goes towards
the sun; a point whose ray meets a mesh lies in shadow. Rays are cast on a grid of every
STEP-th pixel and the mask is upsampled bilinearly: the sun's disc (0.53 deg) gives real
shadows a penumbra of about 1 cm per metre between the caster and the ground, a few pixels for
the casters near the camera, so the soft edge of the upsampling (and of a slight blur that hides
the grid's stair steps) is no worse than the real one.

Leaves let sunlight through: a crown's closed mesh is crossed twice by a ray, and urban
broadleaf crowns pass 10-30 % of direct sun (simgen.materials, FOLIAGE), so a shadow cast by a
porous part is (1 - porosity ** 2) deep.

Skylight is occluded too: the road under and beside a vehicle sees only part of the sky, so even
out of the sun it is darker than open road (the dark band under every real car's bumper, deepest
between its wheels). `sky_occlusion` measures, for ground points near an actor, the share of
cosine-weighted sky that the actors' meshes hide, with a fixed set of rays per point.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from embreex.rtcore_scene import EmbreeScene

from . import facets
from .embree import embree_scene
from .world import Part

STEP = 3  # pixels between shadow rays
SOFTEN = 0.8  # ray-grid cells: a Gaussian that hides the grid's stair steps along shadow edges
T_NEAR = 0.05  # m: a ray starts this far from its surface point (depth precision, flat facets)
# Skylight occlusion varies over the clearance under a vehicle (0.1-0.3 m: 15-40 px at 10 m), far
# more slowly than a shadow's edge: a coarser grid of points, each with SKY_RAYS rays.
SKY_STEP = 6
SKY_RAYS = 32
# A box of height H hides at most (1 - d / sqrt(d^2 + H^2)) / 2 of the sky from a point d beside
# it (an infinitely long wall): 0.05 at d = 2 H, less beside a box of finite length; beyond that
# reach the occlusion is left out.
SKY_REACH = 2.0
# m: how far beyond the rays' own bounds Occluders.along keeps a triangle (float32 rounding of
# the rays and triangles is far smaller)
AXIS_MARGIN = 0.05


@dataclass
class Occluders:
    """World-frame triangles that can cast a shadow, as shared vertices and faces indexing them
    (fewer numbers to copy into Embree, embree_scene: shared vertices are about a fifth of the
    triangles' corners), and each one's shadow depth."""

    vertices: np.ndarray  # (V, 3) float32
    faces: np.ndarray  # (F, 3) int32
    depth: np.ndarray  # (F,) float32, 1 - porosity ** 2
    # Built once: the skylight's rays and the sun's may meet the actors' triangles
    _scene: EmbreeScene | None = field(default=None, init=False, repr=False, compare=False)

    @staticmethod
    def empty() -> Occluders:
        """No triangle: what casts no shadow."""
        return Occluders(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.float32))

    @staticmethod
    def of_triangles(tris: np.ndarray, depth: np.ndarray) -> Occluders:
        """(F, 3, 3) triangles, each corner a vertex of its own."""
        corners = tris.reshape(-1, 3)
        return Occluders(corners, np.arange(len(corners), dtype=np.int32).reshape(-1, 3), depth)

    @staticmethod
    def of_mesh(parts: list[Part], vertices: np.ndarray, faces: np.ndarray) -> Occluders:
        """The parts' triangles as world-frame `vertices` (V, 3) and `faces` (F, 3) indexing
        them, in part order."""
        return Occluders(np.asarray(vertices, np.float32), np.asarray(faces, np.int32), _depths(parts))

    @property
    def tris(self) -> np.ndarray:
        """(F, 3, 3) float32 triangles."""
        return np.take(self.vertices, self.faces, axis=0)

    def scene(self) -> EmbreeScene:
        """An Embree scene of the triangles."""
        if self._scene is None:
            self._scene = embree_scene(self.vertices, self.faces)
        return self._scene

    def shadow(self, origins: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """(N,) float32 shadow depth of the first triangle each ray from `origins` (N, 3) float32
        along the unit `direction` meets, 0 where it meets none."""
        near = self.along(origins, direction)
        prim = near.scene().run(origins, _rays(direction, len(origins)))
        return np.where(prim >= 0, near.depth[np.maximum(prim, 0)], np.float32(0.0))

    def along(self, points: np.ndarray, direction: np.ndarray) -> Occluders:
        """The triangles that a ray from one of `points` (N, 3) along the unit `direction` may
        meet: those not wholly outside the prism the rays sweep, the points' bounding box across
        the direction (AXIS_MARGIN wider) from their lowest point along it upwards. The rest
        cannot change a hit, and a smaller scene is faster to build and to cast into."""
        across = np.cross([0.0, 0.0, 1.0], direction)
        if np.linalg.norm(across) < 1e-6:
            across = np.array([1.0, 0.0, 0.0])
        across /= np.linalg.norm(across)
        axes = np.stack([across, np.cross(direction, across), direction])  # rows: a frame
        p = points @ axes.T
        lo, hi = p.min(axis=0) - AXIS_MARGIN, p.max(axis=0) + AXIS_MARGIN
        # Above each lower bound, below the upper ones across the direction (none along it: the
        # rays run on).
        planes = np.r_[np.c_[axes, -lo], np.c_[-axes[:2], hi[:2]]]
        keep = ~facets.beyond(self.vertices, self.faces, planes)
        return Occluders(self.vertices, self.faces[keep], self.depth[keep])

    @staticmethod
    def join(a: Occluders, b: Occluders) -> Occluders:
        if not len(a.faces) or not len(b.faces):
            return b if not len(a.faces) else a
        return Occluders(np.concatenate([a.vertices, b.vertices]),
                         np.concatenate([a.faces, b.faces + np.int32(len(a.vertices))]),
                         np.concatenate([a.depth, b.depth]))


@dataclass
class WorldScene:
    """An Embree scene of the whole world built for another sensor (the LiDAR's target): its first
    `statics` triangles are the static world's, in the order of World.static; the actors' come
    after them, posed at other times than the camera's."""

    scene: EmbreeScene
    statics: int


@dataclass
class SplitCasters:
    """The sun's casters without a scene of their own: the static world from `world` (the same
    triangles as `static`, so the same hits), the actors at the camera's poses from their own
    scene (built once for the skylight, Occluders.scene). A ray's first hit is the nearer of the
    two; where `world` shows an actor of its own poses first and the camera's actors no nearer,
    the static world beyond it is cast for those few rays in a scene of `static` near them."""

    world: WorldScene
    static: Occluders
    actors: Occluders

    def __post_init__(self) -> None:
        if self.world.statics != len(self.static.faces):
            raise ValueError(f"the world scene holds {self.world.statics} static triangles, "
                             f"the camera's static world {len(self.static.faces)}")

    def shadow(self, origins: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """As Occluders.shadow over the static world and the actors together. Where two
        triangles lie at exactly the same distance either may be taken, as in one scene."""
        dirs = _rays(direction, len(origins))
        hit = self.world.scene.run(origins, dirs, output=1)
        prim, t = hit["primID"], hit["tfar"]
        a_depth, a_t = _first_hits(self.actors, origins, dirs)
        static = (prim >= 0) & (prim < self.world.statics)
        s_depth = np.append(self.static.depth, np.float32(0.0))[np.where(static, prim, self.world.statics)]
        s_t = np.where(static, t, np.float32(np.inf))
        unknown = np.flatnonzero((prim >= self.world.statics) & ~(a_t <= t))
        if len(unknown):
            s_depth[unknown], s_t[unknown] = _first_hits(self.static.along(origins[unknown], direction),
                                                         origins[unknown], dirs[unknown])
        return np.where(a_t < s_t, a_depth, s_depth)


def _rays(direction: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) float32 copies of `direction`, as Embree's rays take them."""
    return np.broadcast_to(direction.astype(np.float32), (n, 3)).copy()


def _first_hits(occluders: Occluders, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per ray, the shadow depth of the first of the triangles it meets and how far along the ray
    (0 and infinity where it meets none)."""
    if not len(occluders.faces):
        return np.zeros(len(origins), np.float32), np.full(len(origins), np.inf, np.float32)
    hit = occluders.scene().run(origins, dirs, output=1)
    met = hit["primID"] >= 0
    return (np.where(met, occluders.depth[np.maximum(hit["primID"], 0)], np.float32(0.0)),
            np.where(met, hit["tfar"], np.float32(np.inf)))


def _depths(parts: list[Part]) -> np.ndarray:
    """(F,) float32 shadow depth of each of the parts' faces: 1 - porosity ** 2."""
    return np.repeat([1.0 - p.material.porosity ** 2 for p in parts],
                     [len(p.mesh.faces) for p in parts]).astype(np.float32)


def _world_points(u: np.ndarray, v: np.ndarray, z: np.ndarray, K: np.ndarray,
                  cam2_from_world: np.ndarray) -> np.ndarray:
    """(N, 3) world points seen at pixels (u, v) with depth z."""
    zc = z.astype(np.float64)
    cam = np.stack([(u - K[0, 2]) * zc / K[0, 0], (v - K[1, 2]) * zc / K[1, 1], zc, np.ones_like(zc)])
    return (np.linalg.inv(cam2_from_world) @ cam)[:3].T


def sun_shadow(occluders: Occluders | SplitCasters, depth: np.ndarray, K: np.ndarray, cam2_from_world: np.ndarray,
               to_sun: np.ndarray, sunlit: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 shadow depth in [0, 1] per pixel (0 = in sun), 0 where depth is 0 (sky).
    `sunlit` (H, W) bool, if given, limits the rays to pixels whose surface faces the sun (a
    shadow changes nothing on the others)."""
    H, W = depth.shape
    v, u = np.mgrid[STEP // 2:H:STEP, STEP // 2:W:STEP]
    z = depth[v, u]
    need = z > 0
    if sunlit is not None:
        need &= sunlit[v, u]
    small = np.zeros(z.shape, np.float32)
    if not need.any() or to_sun[2] <= 0:
        return np.zeros((H, W), np.float32)
    points = _world_points(u[need], v[need], z[need], K, cam2_from_world)
    origins = (points + T_NEAR * to_sun).astype(np.float32)
    small[need] = occluders.shadow(origins, to_sun)
    small = cv2.GaussianBlur(small, (0, 0), SOFTEN)
    full = cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)
    return np.multiply(full, depth > 0, out=full)


def sky_directions(n: int = SKY_RAYS) -> np.ndarray:
    """(n, 3) unit directions about +z, cosine-weighted: points spread evenly over the unit disk
    (the golden-angle spiral) lifted onto the hemisphere (Malley's method), so every ray stands for
    the same share of the skylight a horizontal surface receives."""
    k = np.arange(n) + 0.5
    r, phi = np.sqrt(k / n), k * np.pi * (3.0 - np.sqrt(5.0))
    return np.c_[r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - r ** 2)]


@dataclass
class Reach:
    """Where actors can hide sky: each one's box (actor frame, lo and hi corners) and pose."""

    actor_from_world: np.ndarray  # (A, 4, 4)
    lo: np.ndarray  # (A, 3)
    hi: np.ndarray  # (A, 3)

    def near(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: world points within SKY_REACH box heights of some box in plan view, not
        above it nor more than a metre below it (a road that falls away beside a wheel). Each
        box is first tested by the world-axes bounds of its reach."""
        if not len(self.lo):
            return np.zeros(len(points), bool)
        m = SKY_REACH * (self.hi[:, 2] - self.lo[:, 2])
        lo, hi = self.lo - np.c_[m, m, np.full_like(m, 1.0)], self.hi + np.c_[m, m, 0 * m]
        corners = np.stack([np.where([i & 1, i & 2, i & 4], hi, lo) for i in range(8)], axis=1)
        world_from_actor = np.linalg.inv(self.actor_from_world)
        world = np.einsum("aij,akj->aki", world_from_actor[:, :3, :3], corners) + world_from_actor[:, None, :3, 3]
        wlo, whi = world.min(axis=1), world.max(axis=1)
        pi, ai = np.nonzero(np.all((points[:, None] >= wlo[None]) & (points[:, None] <= whi[None]), axis=2))
        a = self.actor_from_world[ai]
        local = np.einsum("kij,kj->ki", a[:, :3, :3], points[pi]) + a[:, :3, 3]
        inside = np.all((local > lo[ai]) & (local < hi[ai]), axis=1)
        out = np.zeros(len(points), bool)
        out[pi[inside]] = True
        return out


def sky_occlusion(occluders: Occluders, reach: Reach, depth: np.ndarray, ground: np.ndarray,
                  K: np.ndarray, cam2_from_world: np.ndarray) -> np.ndarray:
    """(H, W) float32 share of the sky (cosine-weighted about world up) that `occluders` hide
    from the surface seen at each `ground` pixel; 0 elsewhere and beyond every actor's reach."""
    H, W = depth.shape
    if not len(occluders.faces) or not len(reach.lo):
        return np.zeros((H, W), np.float32)
    v, u = np.mgrid[SKY_STEP // 2:H:SKY_STEP, SKY_STEP // 2:W:SKY_STEP]
    need = ground[v, u] & (depth[v, u] > 0)
    points = _world_points(u[need], v[need], depth[v, u][need], K, cam2_from_world)
    close = reach.near(points)
    small = np.zeros(v.shape, np.float32)
    if close.any():
        dirs = sky_directions().astype(np.float32)
        origins = (points[close] + [0.0, 0.0, T_NEAR]).astype(np.float32)
        prim = occluders.scene().run(np.repeat(origins, len(dirs), axis=0), np.tile(dirs, (len(origins), 1)))
        hidden = np.where(prim >= 0, occluders.depth[np.maximum(prim, 0)], 0.0).reshape(-1, len(dirs))
        idx = np.flatnonzero(need.ravel())[close]
        small.ravel()[idx] = hidden.mean(axis=1)
    # Upsampled bilinearly between grid points (each lands on its own pixel), over ground points
    # only (a normalised interpolation): no halo of the unlit value at a vehicle's outline.
    mx = np.broadcast_to(((np.arange(W) - SKY_STEP // 2) / SKY_STEP).astype(np.float32), (H, W))
    my = np.broadcast_to(((np.arange(H) - SKY_STEP // 2) / SKY_STEP).astype(np.float32)[:, None], (H, W))
    weight = need.astype(np.float32)
    sw, ww = (cv2.remap(a, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
              for a in (small * weight, weight))
    out = np.where(ww > 1e-6, sw / np.maximum(ww, 1e-6), 0.0).astype(np.float32)
    return out * ground * (depth > 0)
