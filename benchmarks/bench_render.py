"""Camera rendering speed and complete-frame throughput of the scene generator.

Prints (1) the world sampling time (scenery and actor meshes) and the render time per 1242x375
frame of scenes/urban.yaml, split into scene build, segmentation+depth pass (simgen.instance_pass,
drawn first), colour pass (4x MSAA, with the culling of its hidden triangles; the actors'
occlusion of the sky is computed while llvmpipe draws it, and counted here), sun shadows
(Embree; the static world from the spec's LiDAR's scene, built first as simgen.generate builds
it and timed on its own), the look and camera (fog/rain/sensor, exposure,
noise, demosaicing; beside it the same with the camera's rectification off, the CFA on the output's
own pixels, timed in the same loop) and the label derivation; (2) complete frames per second
(sample + render + labels + all files, no LiDAR, and with the spec's LiDAR) of `simgen.generate`
with 1 and 2 worker processes, over the whole run (process start-up included) and in its steady
state (from the first tenth of the frames written to the last: what a long run sees).

    .venv/bin/python benchmarks/bench_render.py [--frames N] [--gen-frames M] [--spec scenes/urban.yaml]
        [--breakdown-only | --throughput-only] [--workers 2] [--lidar-only]
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import tempfile
import time
from pathlib import Path

import kitti  # noqa: F401  (first: it pins the kernels and OpenBLAS's threads before numpy loads)
import numpy as np
from pyrender.constants import RenderFlags

from simgen.factors import factor_rng
from simgen.generate import generate
from simgen.labels import derive
from simgen.lidar import build_target, preset
from simgen.look import apply_look
from simgen.render import HEADROOM, build_scene, renderer, shade, skylight
from simgen.sample import sample_world
from simgen.shadows import WorldScene
from simgen.spec import load_spec
from testbed.backends import LocalBackend


def render_breakdown(spec, n: int) -> None:
    worlds, sample_ms = [], []
    for i in range(n):
        t0 = time.perf_counter()
        worlds.append(sample_world(spec, spec.seed, i))
        sample_ms.append(1000 * (time.perf_counter() - t0))
    r = renderer(worlds[0].rig.width, worlds[0].rig.height)
    warm = build_scene(worlds[0])  # warm-up: shaders compile on the first render
    warm.colour_pass(r, warm.instance_pass(r))
    t = {"build": [], "colour": [], "seg+depth": [], "shadows": [], "look": [], "labels": [],
         "look, rectification off": [], "lidar scene": []}
    for w in worlds:
        tl = time.perf_counter()
        scene = lidar_scene(spec, w)
        t0 = time.perf_counter()
        built = build_scene(w)
        built.casters.world = scene
        t1 = time.perf_counter()
        seen = built.instance_pass(r)
        t2 = time.perf_counter()
        inst, depth = seen.instance, seen.depth
        lit = bool(built.flags & RenderFlags.RGBA)
        if lit:  # as simgen.render.render: the sky's occlusion while llvmpipe draws the colour pass
            color, sky = built.colour_pass(r, seen, lambda: skylight(w, depth, inst, built.casters))
        else:
            color, sky = built.colour_pass(r, seen), None
        t3 = time.perf_counter()
        rgb = shade(w, color, depth, inst, built.casters, sky) if lit else color[..., :3]
        t4 = time.perf_counter()
        apply_look(rgb, depth, w.rig.intrinsics(), w.weather, w.light, w.sensor,
                   factor_rng(0, 0, "look"), HEADROOM if lit else 1.0, w.camera)
        t5 = time.perf_counter()
        derive(w, inst, spec.labels)
        t6 = time.perf_counter()
        apply_look(rgb, depth, w.rig.intrinsics(), w.weather, w.light, w.sensor, factor_rng(0, 0, "look"),
                   HEADROOM if lit else 1.0, dataclasses.replace(w.camera, rectified=False))
        t7 = time.perf_counter()
        for k, a, b in (("build", t0, t1), ("seg+depth", t1, t2), ("colour", t2, t3),
                        ("shadows", t3, t4), ("look", t4, t5), ("labels", t5, t6),
                        ("look, rectification off", t6, t7), ("lidar scene", tl, t0)):
            t[k].append(1000 * (b - a))
    actors = np.mean([len(w.actors) for w in worlds])
    print(f"{spec.name}: {n} frames of {worlds[0].rig.width}x{worlds[0].rig.height}, "
          f"{actors:.0f} actors per world on average")
    print(f"  {'sample':10s} {np.median(sample_ms):7.1f} ms median  {np.mean(sample_ms):7.1f} ms mean "
          "(simgen.sample_world: scenery and actor meshes)")
    for k, v in t.items():
        print(f"  {k:10s} {np.median(v):7.1f} ms median  {np.mean(v):7.1f} ms mean")
    print("  (the look's first frame builds the rectification maps, once a process; the lidar scene is the")
    print("  spec's LiDAR's Embree scene, built before the render as simgen.generate does: the sun's shadows use it)")
    render = sum(np.array(t[k]) for k in ("build", "colour", "seg+depth", "shadows"))
    print(f"  RENDER (build + colour + seg/depth + shadows): {np.median(render):.1f} ms median per frame")


def lidar_scene(spec, world) -> WorldScene | None:
    """The spec's LiDAR's scene of `world` as simgen.generate hands it to the render; None without one."""
    if spec.lidar is None:
        return None
    target = build_target(world, preset(spec.lidar.preset, beams=spec.lidar.beams, max_range=spec.lidar.max_range))
    return WorldScene(target.scene, target.first_actor)


def throughput(spec, n: int, workers: int, lidar: bool) -> None:
    s = spec if lidar else spec.model_copy(update={"lidar": None})
    out = Path(tempfile.mkdtemp(prefix="bench_render_", dir="data" if Path("data").is_dir() else None))
    try:
        t0 = time.perf_counter()
        with LocalBackend(workers) as backend:
            generate(s, out, frames=n, backend=backend)
        dt = time.perf_counter() - t0
        # A frame's meta/ file is the last it writes (simgen.generate.make_frame).
        done = np.sort([p.stat().st_mtime for p in (out / "training" / "meta").glob("*.json")])
    finally:
        shutil.rmtree(out)
    k = max(1, n // 10)
    steady = (len(done) - k) / (done[-1] - done[k - 1]) if len(done) > k else float("nan")
    print(f"  generate {n} frames, {workers} worker(s), LiDAR {'on' if lidar else 'off'}: "
          f"{dt:.1f} s, {n / dt:.2f} frames/s (process start-up included); "
          f"{steady:.2f} frames/s from frame {k} written to the last")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--spec", default="scenes/urban.yaml")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--gen-frames", type=int, help="frames of each throughput run (default: --frames)")
    only = ap.add_mutually_exclusive_group()
    only.add_argument("--breakdown-only", action="store_true", help="skip the throughput runs")
    only.add_argument("--throughput-only", action="store_true", help="skip the breakdown")
    ap.add_argument("--workers", type=int, action="append", help="throughput with this many workers "
                    "(repeat for several; default 1 and 2)")
    ap.add_argument("--lidar-only", action="store_true", help="throughput with the spec's LiDAR only")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    if not args.throughput_only:
        render_breakdown(spec, args.frames)
    for lidar in () if args.breakdown_only else (True,) if args.lidar_only else (False, True):
        for workers in args.workers or (1, 2):
            throughput(spec, args.gen_frames or args.frames, workers, lidar)


if __name__ == "__main__":
    main()
