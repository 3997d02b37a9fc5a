"""One full 360-degree sweep: one batched Embree query, then vectorised sensor physics.

Per ray, in order: exact first hit on the world's meshes (Embree, origin moving with the
ego vehicle), motion correction for hits on moving actors (see target.py), range noise
(fixed per-laser bias + per-ray Gaussian), received power from reflectivity, incidence and
distance with weather extinction, the detection threshold, random drop-out, weather echoes
(weather.py), and the reported reflectance. No Python loop runs per ray.

Reported reflectance: the HDL-64E reports range-compensated intensity, so a return reads
rho * cos(incidence) * exp(-2 beta d), rising as (saturation_range / d)^2 closer than
saturation_range where the receiver over-reads, clipped to [0, 1] and quantised to 0.01 as
in KITTI's files (which is why very dark or grazing returns read exactly 0).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..world import World
from .rays import ray_table
from .spec import LidarSpec
from .target import Target, build_target
from .weather import clutter, total_extinction

CLUTTER_ID = -1


@dataclass
class LidarScan:
    """One sweep in the LiDAR frame; each point in the sensor frame at its own firing time."""

    points: np.ndarray  # (N, 4) float32 x, y, z, reflectance
    ring: np.ndarray  # (N,) uint8, 0 = top beam
    azimuth: np.ndarray  # (N,) float32 firing azimuth, rad, atan2(y, x)
    time: np.ndarray  # (N,) float32 s relative to the camera trigger
    actor_id: np.ndarray  # (N,) int32: > 0 actor, 0 background, -1 weather clutter

    def __len__(self) -> int:
        return len(self.points)

    def select(self, mask: np.ndarray) -> LidarScan:
        return LidarScan(**{f.name: getattr(self, f.name)[mask] for f in fields(self)})

    def point_counts(self) -> dict[int, int]:
        """Points per actor id (> 0 only): the per-label LiDAR point count."""
        ids, counts = np.unique(self.actor_id[self.actor_id > 0], return_counts=True)
        return {int(i): int(c) for i, c in zip(ids, counts)}


def _motion_shift(tgt: Target, slot: np.ndarray, t_ray: np.ndarray, hit_w: np.ndarray,
                  normal: np.ndarray, d_w: np.ndarray) -> np.ndarray:
    """Range change that keeps each hit on its moving facet at the ray's own time.

    The hit material point moves by the actor's rigid motion between its placement time and
    the ray time (delta); the facet plane moves with it, so along the ray the range changes by
    (n . delta) / (n . d): exact for pure translation, first order in the small yaw.
    """
    dt = t_ray - tgt.placed_time[slot]
    c = tgt.placed_origin[slot]
    a = tgt.yaw_rate[slot] * dt
    rel = hit_w - c
    cos_a, sin_a = np.cos(a), np.sin(a)
    delta = tgt.velocity[slot] * dt[:, None]
    delta[:, 0] += (cos_a - 1.0) * rel[:, 0] - sin_a * rel[:, 1]
    delta[:, 1] += sin_a * rel[:, 0] + (cos_a - 1.0) * rel[:, 1]
    nd = np.einsum("ij,ij->i", normal, d_w)
    safe = np.abs(nd) > 1e-3
    return np.where(safe, np.einsum("ij,ij->i", normal, delta) / np.where(safe, nd, 1.0), 0.0)


def scan(world: World, spec: LidarSpec, seed: int | np.random.Generator,
         target: Target | None = None) -> LidarScan:
    """Scan `world` with `spec`. Same world, spec and seed: the same points, bit for bit.

    `target` (from build_target(world, spec)) can be passed to reuse the Embree scene.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    rays = ray_table(spec)
    tgt = target if target is not None else build_target(world, spec)
    n = len(rays.time)

    rot = world.lidar_pose[:3, :3]
    d_w = (rays.dirs @ rot.T).astype(np.float32)
    origins = np.empty((n, 3), np.float32)
    origins[:] = world.lidar_pose[:3, 3]
    ego_v = np.asarray(world.ego_velocity, dtype=float)
    if spec.motion and np.any(ego_v):
        origins += (rays.time[:, None] * ego_v[None, :]).astype(np.float32)

    far = spec.max_range + 1.0
    if tgt.n_triangles:
        res = tgt.scene.run(origins, d_w, dists=far, output=1)
        idx = np.flatnonzero(res["primID"] >= 0)
    else:
        res, idx = None, np.zeros(0, np.int64)
    tri = res["primID"][idx] if res is not None else idx
    r = res["tfar"][idx].astype(np.float64) if res is not None else np.zeros(0)
    ring = rays.ring[idx]
    ng = res["Ng"][idx] if res is not None else np.zeros((0, 3), np.float32)
    dh = d_w[idx]
    ng_norm = np.sqrt(np.einsum("ij,ij->i", ng, ng))
    cos_inc = np.abs(np.einsum("ij,ij->i", ng, dh)) / np.maximum(ng_norm, 1e-30)

    if spec.motion and len(tgt.actor_ids):
        slot = tgt.tri_slot[tri]
        on_actor = np.flatnonzero(slot >= 0)
        moving = (np.any(tgt.velocity != 0, axis=1) | (tgt.yaw_rate != 0))[slot[on_actor]]
        sel = on_actor[moving]
        if len(sel):
            hit_w = origins[idx[sel]] + r[sel, None] * dh[sel]
            r[sel] += _motion_shift(tgt, slot[sel], rays.time[idx[sel]], hit_w,
                                    ng[sel].astype(np.float64), dh[sel].astype(np.float64))

    if spec.noise_sigma > 0 or spec.bias_sigma > 0:
        r = r + spec.laser_biases()[ring] + rng.normal(0.0, spec.noise_sigma, len(r))

    beta = total_extinction(world.weather) if spec.weather else 0.0
    rho_cos = tgt.tri_refl[tri] * cos_inc
    keep = (r >= spec.min_range) & (r <= spec.max_range)
    if spec.detection:
        keep &= spec.power(rho_cos, r, beta) >= 1.0
    if spec.dropout > 0:
        keep &= rng.random(len(r)) >= spec.dropout
    aid = tgt.tri_actor[tri]

    if spec.weather and (world.weather.fog_extinction > 0 or world.weather.rain_rate > 0):
        full_r = np.full(n, np.inf)
        full_r[idx[keep]] = r[keep]
        full_p = np.zeros(n)
        full_p[idx[keep]] = spec.power(rho_cos[keep], r[keep], beta)
        full_rc = np.zeros(n)
        full_rc[idx[keep]] = rho_cos[keep]
        full_aid = np.zeros(n, np.int32)
        full_aid[idx[keep]] = aid[keep]
        c_d, c_rho = clutter(world.weather, n, rng)
        ok = (c_d >= spec.min_range) & (c_d < full_r) & (c_d <= spec.max_range)
        c_p = np.zeros(n)
        c_p[ok] = spec.power(c_rho[ok], c_d[ok], beta)
        wins = ok & (c_p >= 1.0) & (c_p > full_p)
        full_r[wins], full_rc[wins], full_aid[wins] = c_d[wins], c_rho[wins], CLUTTER_ID
        idx = np.flatnonzero(np.isfinite(full_r))
        r, rho_cos, aid = full_r[idx], full_rc[idx], full_aid[idx]
    else:
        idx, r, rho_cos, aid = idx[keep], r[keep], rho_cos[keep], aid[keep]

    refl = rho_cos * (np.exp(-2.0 * beta * r) if beta > 0 else 1.0)
    near = r < spec.saturation_range
    if np.any(near):
        refl[near] *= (spec.saturation_range / r[near]) ** 2
    refl = np.round(np.clip(refl, 0.0, 1.0) * 100.0) / 100.0

    points = np.empty((len(idx), 4), np.float32)
    points[:, :3] = rays.dirs[idx] * r[:, None]
    points[:, 3] = refl
    return LidarScan(points=points, ring=rays.ring[idx], azimuth=rays.azimuth[idx],
                     time=rays.time[idx].astype(np.float32), actor_id=aid.astype(np.int32))
