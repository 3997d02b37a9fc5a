"""One full 360-degree sweep: one batched Embree query (and a few small ones for the rays that
pass glass or leaves), then vectorised sensor physics. No Python loop runs per ray.

Per ray, in order:
1. the exact first hit on the world's meshes (Embree, origin moving with the ego vehicle);
2. pass-through (`_pass_through`): a beam that meets glass goes on (a clean pane reflects
   specularly, away from the sensor, so its own echo is never reported) and the echo from behind
   loses the pane's two-way transmittance; in a car's glasshouse it ends on the cabin where the
   camera's glass shows seats, head restraints or trim (CABIN), else it passes the far pane too or
   goes down into the body below the windows; a beam that meets a porous material (leaves) goes on
   with probability `porosity`. Those rays are cast again, batched, from PASS_STEP behind the
   hit, up to MAX_PASSES surfaces; a ray that goes on into nothing returns nothing. A beam that
   ends on a façade inside one of its windows (the camera's façade tiles show where: windows.py)
   goes through the glazing and ends behind it, on a curtain or in the room (`_through_windows`);
3. motion correction for hits on moving actors (see target.py);
4. the echo strength rho_eff = reflectivity * cos(incidence) ** k * (glass losses): the
   material's reading at its incidence (values and sources: simgen.materials);
5. detection: rho_eff * exp(-2 beta d) must reach the threshold 0.1 * (d / 50 m) ** gamma
   (LidarSpec: dark, grazing and far surfaces drop out first), then the laser's own random
   loss, then range noise (fixed per-laser bias + per-ray Gaussian);
6. weather echoes (weather.py);
7. on an onboard rig, the directions the car under the sensor hides return nothing (platform.py:
   measured on KITTI's scans);
8. the reported reflectance.

Reported reflectance (constants and the KITTI measurements behind them: LidarSpec). The
HDL-64E reports a range-compensated intensity out to `compensation_range` (36 m): a surface reads
about its rho_eff there (KITTI's road reads the same median from 4 to 40 m). A return reads
    s = g_laser * e * rho_eff * exp(-2 beta d) * min(1, (compensation_range / d) ** gamma),
g_laser the laser's gain (log-normal, drawn once per sensor unit: the 64 lasers differ in
calibrated intensity), e the per-return scatter (log-logistic), and the last factor the echo's
fall beyond the compensated range (KITTI's far returns read dimmer: the road's nonzero median is
0.17 at 40-50 m against 0.24 near). A return reads 0 where its echo, g_laser * e' * rho_eff *
exp(-2 beta d) with e' a scatter draw of its own, is below refl_floor_power * 0.1 * (d / 50 m)
** gamma: the echo power under which the unit's intensity clamps to its minimum (half of
KITTI's road reads 0 at 37 m, 74 % at 40-60 m), decided apart from the reading's scatter, since
the road's nonzero median does not rise as its zeros do. s also reads 0 below refl_floor, the
fixed floor of the lowest readings. The rest is rounded to refl_step (0.01) and capped at
refl_max (0.99), as KITTI writes it. Near range: no over-read (KITTI's returns within 5 m read 0.99 less
often than farther ones and have the same nonzero median); KITTI's many zeros within 2.5 m
(88 %) are not modelled (too few returns there, 0.13 %, to tell the sensor from what it sees).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..materials import CURTAIN_REFLECTIVITY, ROOM_REFLECTIVITY, WINDOW_TRANSMITTANCE
from ..textures import glass_cabin_bands
from ..world import World
from .draws import CLAMP, DETECT, PASS, normals, ray_words, sweep_key, to_uniform, uniforms
from .kernels import (detect_rays, exact_hits, pass_apply, pass_candidates, pass_prepare, ray_origins,
                      read_returns, window_returns)
from .platform import hidden_rays
from .rays import RayTable, ray_table
from .spec import LidarSpec
from .target import Target, build_target
from .weather import clutter, total_extinction
from .windows import CURTAIN_GAP_M, ROOM_DEPTH_M

CLUTTER_ID = -1
# Zero-length arrays: a kernel's "none" for an optional per-ray input.
_NONE = np.zeros(0, np.float32)
_NONE3 = np.zeros((0, 3), np.float32)
_NONE_BOOL = np.zeros(0, bool)
_NONE64 = np.zeros(0, np.float64)
# A ray that goes on is cast again from just behind the surface it leaves (float32 positions out
# to 120 m are good to 10 micrometres, so it cannot meet that surface again).
PASS_STEP = 1e-3  # m
# A glass solid whose far side lies closer than this behind the entry is one pane (the meshes'
# window boxes are 2 to 8 cm thick); a thicker one (a car's glasshouse) has a pane at each side.
PANE_MAX = 0.1  # m
MAX_PASSES = 4  # surfaces one ray may go on through: a crown's two faces, two glasshouses
# A car's cabin where the camera's glass shows it (trim and cushions, seat backs, head restraints:
# textures.glass_cabin_bands) ends the beam CABIN_DEPTH_M behind the pane it entered: a side window
# stands about 0.1 m outboard of the door trim, an outboard seat about 0.1 m inboard of it, and a
# rear window 0.2-0.4 m from the head restraints behind it (no survey: car drawings).
CABIN = glass_cabin_bands()
CABIN_DEPTH_M = 0.25
# Fresnel reflectance of glass at normal incidence, ((n - 1) / (n + 1)) ** 2 for n = 1.52 (soda-lime
# glass at 905 nm); Schlick's approximation gives its rise towards grazing incidence.
GLASS_R0 = 0.0426


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

    def point_counts(self) -> dict[int, int]:
        """Points per actor id (> 0 only): the per-label LiDAR point count."""
        ids, counts = np.unique(self.actor_id[self.actor_id > 0], return_counts=True)
        return {int(i): int(c) for i, c in zip(ids, counts)}


@dataclass(frozen=True)
class _Sweep:
    """What a sweep needs that depends on its spec alone, made once per spec and process."""

    rays: RayTable
    bias: np.ndarray  # (beams,) float32 per-laser range bias, m
    gain: np.ndarray  # (beams,) float32 per-laser reading gain
    dropout: np.ndarray  # (beams,) float32 per-laser loss rate
    zero: np.ndarray  # (beams,) float32 per-laser share of readings of 0
    hidden: np.ndarray  # (N,) bool: the rays the recording car hides (onboard rigs)
    scatter: np.ndarray  # the reading's scatter quantiles (_scatter_quantiles)
    need_exp: np.float32  # LidarSpec.threshold: range ** need_exp * need_scale, in float32
    need_scale: np.float32
    need0: np.float32  # the threshold at the compensation range


@lru_cache(maxsize=16)
def _sweep(spec: LidarSpec) -> _Sweep:
    """The sweep constants of `spec` (the arrays are shared: callers never write into them)."""
    f32 = np.float32
    g = spec.range_exponent
    return _Sweep(rays=ray_table(spec), bias=spec.laser_biases().astype(f32),
                  gain=spec.laser_gains().astype(f32), dropout=spec.laser_dropouts().astype(f32),
                  zero=spec.laser_zero_shares().astype(f32), hidden=hidden_rays(spec),
                  scatter=_scatter_quantiles(spec.reading_sigma), need_exp=f32(g),
                  need_scale=f32(0.1 / spec.dark_range ** g),
                  need0=f32(spec.threshold(np.float64(spec.compensation_range))))


def _origins(world: World, spec: LidarSpec, rays: RayTable, n: int) -> np.ndarray:
    """(n, 3) ray origins: with motion, one per firing column (moving with the ego vehicle)
    shared by its lasers; else the LiDAR's position for every ray; plus, where the lasers fire
    from sources of their own, the ray's source turned with the rig (kernels.ray_origins)."""
    ego_v = np.asarray(world.ego_velocity, dtype=np.float64)
    moving = spec.motion and bool(ego_v.any())
    source = (_world_source(spec, tuple(world.lidar_pose[:3, :3].ravel().tolist()))
              if rays.source is not None else _NONE3)
    origins = np.empty((n, 3), np.float32)
    ray_origins(world.lidar_pose[:3, 3], ego_v if moving else _NONE64, rays.time[:rays.columns], source,
                origins)
    return origins


def _query(tgt: Target, spec: LidarSpec, origins: np.ndarray, d_w: np.ndarray, n: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ray's first hit (module docstring, step 1): triangle (-1: none), range and
    unnormalised geometric normal, one batched Embree query."""
    if not tgt.n_triangles:
        return (np.full(n, -1, np.int32), np.full(n, np.inf, np.float32),
                np.zeros((n, 3), np.float32))
    return _cast(tgt, spec, origins, d_w)


def _cast(tgt: Target, spec: LidarSpec, origins: np.ndarray, dirs: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One batched Embree query: each ray's triangle (-1: none), and its range and normal from
    that triangle's plane (kernels.exact_hits: the same bits on every CPU)."""
    res = tgt.scene.run(origins, dirs, dists=spec.max_range + 1.0, output=1)
    exact_hits(res["primID"], res["tfar"], res["Ng"], origins, dirs, tgt.tri_plane)
    return res["primID"], res["tfar"], res["Ng"]


def _pass_through(tgt: Target, spec: LidarSpec, key: np.ndarray, origins: np.ndarray,
                  d_w: np.ndarray, prim: np.ndarray, tfar: np.ndarray, ng: np.ndarray,
                  cand: np.ndarray) -> np.ndarray | None:
    """Rays through glass and leaves (module docstring, step 2): at most MAX_PASSES rounds of one
    batched Embree query of the rays that go on (kernels.pass_prepare, pass_apply). A ray that
    enters glass leaves the glass solid where its face planes say, so a car's glasshouse costs
    one query, not two. Updates `prim`, `tfar` and `ng` in place (a ray that goes on into
    nothing gets prim -1); returns each ray's two-way glass loss (None: no glass met). Each
    candidate draws one uniform of its own per surface (draws.PASS + the round)."""
    loss = np.ones(len(prim), np.float32)
    any_glass = False
    for k in range(MAX_PASSES):
        if not len(cand):
            break
        u = uniforms(key, cand, PASS + k)
        sel, o2, d2, start, glass = pass_prepare(cand, u, prim, tfar, ng, origins, d_w, tgt.tri_inv_ng,
                                                 tgt.tri_mat, tgt.mat_transmittance, tgt.mat_porosity,
                                                 tgt.tri_glass, tgt.glass_planes, loss, PANE_MAX,
                                                 GLASS_R0, PASS_STEP, CABIN, CABIN_DEPTH_M)
        any_glass = any_glass or glass > 0
        if not len(sel):
            cand = sel
            break
        cand = pass_apply(sel, start, *_cast(tgt, spec, o2, d2), prim, tfar, ng, tgt.tri_passes)
    prim[cand] = -1  # still going on after MAX_PASSES surfaces: nothing comes back
    return loss if any_glass else None


def _through_windows(tgt: Target, origins: np.ndarray, d_w: np.ndarray, prim: np.ndarray,
                     tfar: np.ndarray, loss: np.ndarray | None
                     ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Rays that ended on a façade's window go on into the room behind it (module docstring,
    step 2; kernels.window_returns). Updates `tfar` in place; returns the glass loss (None: no
    glass met) and each ray's reflectivity from behind a window (-1: none; None: no window met)."""
    wl = tgt.windows
    out = np.ones(len(prim), np.float32) if loss is None else loss
    refl = np.full(len(prim), -1.0, np.float32)
    hits = window_returns(prim, tfar, d_w, origins, wl.tri_wall, wl.walls, wl.panes, wl.n_panes, out,
                          refl, WINDOW_TRANSMITTANCE, GLASS_R0, ROOM_DEPTH_M, CURTAIN_GAP_M,
                          ROOM_REFLECTIVITY, CURTAIN_REFLECTIVITY)
    return (out, refl) if hits else (loss, None)


def _detect(spec: LidarSpec, sweep: _Sweep, words: np.ndarray, beta: float, tgt: Target,
            origins: np.ndarray, d_w: np.ndarray, prim: np.ndarray, tfar: np.ndarray, ng: np.ndarray,
            loss: np.ndarray | None, refl: np.ndarray | None, hidden: np.ndarray):
    """Steps 3-5 of the module docstring (kernels.detect_rays): the kept rays (none of
    `hidden`), their true range, rho_eff, detection threshold (on the true range: the echo's
    power does not see the noise), actor id and the uniform of the reading's scatter. Each ray
    draws one uniform of its own (its block's word draws.DETECT: drop-out, then the reading)."""
    e32 = _NONE
    ext = np.exp(np.float32(-2.0 * beta) * tfar) if beta > 0 else e32
    u = to_uniform(words[DETECT])
    motion = spec.motion and tgt.first_moving < tgt.n_triangles
    rays = sweep.rays
    return detect_rays(prim, tfar, ng, d_w, origins, tgt.tri_inv_ng, e32 if loss is None else loss,
                       e32 if refl is None else refl, tgt.tri_refl, tgt.tri_expo, tgt.tri_actor,
                       sweep.need_exp, sweep.need_scale, hidden, ext, u, spec.beams, rays.columns,
                       sweep.dropout, sweep.zero, spec.detection, spec.min_range, spec.max_range, motion,
                       tgt.first_moving, tgt.tri_slot, rays.time, tgt.placed_time, tgt.placed_origin,
                       tgt.velocity, tgt.yaw_rate, spec.range_exponent)


def _weather_echoes(world: World, spec: LidarSpec, rng: np.random.Generator, n: int, beta: float,
                    idx: np.ndarray, r: np.ndarray, rho: np.ndarray,
                    aid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The kept returns with weather echoes that beat them (or hit rays that returned nothing):
    an echo wins where it is nearer and stronger than the ray's own return."""
    full_r = np.full(n, np.inf)
    full_r[idx] = r
    full_p = np.zeros(n)
    full_p[idx] = spec.power(rho, r, beta)
    full_rc = np.zeros(n, np.float32)
    full_rc[idx] = rho
    full_aid = np.zeros(n, np.int32)
    full_aid[idx] = aid
    c_d, c_rho = clutter(world.weather, n, rng)
    ok = (c_d >= spec.min_range) & (c_d < full_r) & (c_d <= spec.max_range)
    c_p = np.zeros(n)
    c_p[ok] = spec.power(c_rho[ok], c_d[ok], beta)
    wins = ok & (c_p >= 1.0) & (c_p > full_p)
    full_r[wins], full_rc[wins], full_aid[wins] = c_d[wins], c_rho[wins], CLUTTER_ID
    idx = np.flatnonzero(np.isfinite(full_r))
    return idx, full_r[idx].astype(np.float32), full_rc[idx], full_aid[idx]


def _read(spec: LidarSpec, sweep: _Sweep, key: np.ndarray, words: np.ndarray, beta: float,
          idx: np.ndarray, r: np.ndarray, rho: np.ndarray, need: np.ndarray, v: np.ndarray):
    """Steps 5 (range noise) and 8 (reflectance) of the module docstring (kernels.read_returns):
    the (N, 4) points and each return's ring, azimuth and time. Each return's ray draws one
    normal for its range noise (draws.normals) and, with a reading scatter, one uniform for the
    clamp's own scatter draw (its block's word draws.CLAMP). `v`
    (kernels.detect_rays) is -1 where the laser reads 0, else a uniform that picks the reading's
    scatter from _scatter_quantiles."""
    f32 = np.float32
    ext = np.exp(f32(-2.0 * beta) * r) if beta > 0 else _NONE
    noisy = spec.noise_sigma > 0 or spec.bias_sigma > 0
    noise = normals(key, idx, words) if noisy else _NONE
    clamp_v = to_uniform(words[CLAMP, idx]) if spec.reading_sigma > 0 else v
    rays = sweep.rays
    source = rays.source if rays.source is not None else _NONE3
    return read_returns(idx, r, rho, need, v, clamp_v, sweep.scatter, ext, noise, f32(spec.noise_sigma),
                        sweep.bias, sweep.gain, f32(spec.refl_floor_power), sweep.need0,
                        f32(spec.refl_floor), f32(1.0 / spec.refl_step),
                        f32(round(spec.refl_max / spec.refl_step)), rays.dirs4, source, rays.ring,
                        rays.azimuth, rays.time32)


@lru_cache(maxsize=8)
def _scatter_quantiles(sigma: float, n: int = 4096) -> np.ndarray:
    """The reading's scatter factor, log-logistic whose log has robust sd `sigma` (1.4826 x the
    median absolute deviation, the statistic measured on KITTI): (v / (1 - v)) ** a for a
    uniform v, a = sigma / (1.4826 ln 3) (log(v / (1 - v)) has median absolute deviation ln 3),
    tabulated at the centres of n equal steps of v (a lookup, not a power, per return; the
    table's steps are 0.02 % of the factor at the median and it spans x0.18 to x5.6 for
    sigma 0.31)."""
    v = (np.arange(n) + 0.5) / n
    return ((v / (1.0 - v)) ** (sigma / (1.4826 * np.log(3.0)))).astype(np.float32)


def scan(world: World, spec: LidarSpec, seed: int | np.random.Generator,
         target: Target | None = None) -> LidarScan:
    """Scan `world` with `spec`. Same world, spec and seed: the same points, bit for bit.

    `target` (from build_target(world, spec)) can be passed to reuse the Embree scene.
    Arithmetic runs in float32 (1e-5 m at 100 m) except the motion correction. The seed's
    generator gives the sweep's key (draws: each ray's numbers are its own), then the weather's
    echoes.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    key = sweep_key(rng)
    sweep = _sweep(spec)
    rays = sweep.rays
    tgt = target if target is not None else build_target(world, spec)
    n = len(rays.time)
    words = ray_words(key, n)

    d_w = _world_dirs(spec, tuple(world.lidar_pose[:3, :3].ravel().tolist()))
    origins = _origins(world, spec, rays, n)
    prim, tfar, ng = _query(tgt, spec, origins, d_w, n)
    loss = refl = None
    if spec.transmission and tgt.n_triangles:
        cand = pass_candidates(prim, tgt.tri_passes)
        if len(cand):
            loss = _pass_through(tgt, spec, key, origins, d_w, prim, tfar, ng, cand)
        if tgt.windows.n_walls:
            loss, refl = _through_windows(tgt, origins, d_w, prim, tfar, loss)

    beta = total_extinction(world.weather) if spec.weather else 0.0
    onboard = world.rig is not None and world.rig.kind == "onboard"  # the car under the sensor hides
    hidden = sweep.hidden if onboard else _NONE_BOOL
    idx, r, rho, need, aid, v = _detect(spec, sweep, words, beta, tgt, origins, d_w, prim, tfar, ng, loss,
                                        refl, hidden)
    if spec.weather and (world.weather.fog_extinction > 0 or world.weather.rain_rate > 0):
        kept = np.full(n, -1.0, np.float32)
        kept[idx] = v
        idx, r, rho, aid = _weather_echoes(world, spec, rng, n, beta, idx, r, rho, aid)
        need = spec.threshold(r)
        v = kept[idx]  # a clutter echo takes its ray's uniform, or reads 0 if the ray had none
        if onboard:  # nor does a weather echo come back from a hidden direction
            seen = ~hidden[idx]
            idx, r, rho, need, aid, v = (a[seen] for a in (idx, r, rho, need, aid, v))
    points, ring, azimuth, time = _read(spec, sweep, key, words, beta, idx, r, rho, need, v)
    return LidarScan(points=points, ring=ring, azimuth=azimuth, time=time, actor_id=aid)


@lru_cache(maxsize=16)
def _world_dirs(spec: LidarSpec, rot: tuple[float, ...]) -> np.ndarray:
    """Ray directions in the world frame, cached: rigs keep their orientation across frames.

    Elementwise, not a BLAS matmul: the (N, 3) @ (3, 3) sgemm measured 18 ms inside scan
    (probably OpenBLAS threads contending with Embree's TBB workers) against 0.1 ms alone.
    """
    return _rotated(ray_table(spec).dirs32, rot)


@lru_cache(maxsize=16)
def _world_source(spec: LidarSpec, rot: tuple[float, ...]) -> np.ndarray:
    """Where each ray starts relative to the LiDAR's origin, in the world frame (RayTable.source
    rotated with the rig), cached like `_world_dirs`."""
    return _rotated(ray_table(spec).source, rot)


def _rotated(a: np.ndarray, rot: tuple[float, ...]) -> np.ndarray:
    """(N, 3) float32 rows rotated by the row-major 3 x 3 `rot`, elementwise (see `_world_dirs`)."""
    m = np.asarray(rot, dtype=np.float32).reshape(3, 3)
    return np.ascontiguousarray(a[:, 0:1] * m[:, 0] + a[:, 1:2] * m[:, 1] + a[:, 2:3] * m[:, 2])
