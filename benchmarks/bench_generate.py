"""`testbed generate` frames a second, this working tree against a base commit, in one run.

Each round runs the command line of both checkouts one after the other (the base checked out in a
temporary git worktree; `PYTHONPATH` points at each), writing every file of `--frames` frames of
`scenes/urban.yaml` (each checkout's own) with 2 workers. A frame counts as written when its
`meta/` file appears, the last file a frame writes; the steady state is the frames written after
the first `--warm` divided by the time they took, so process start-up and the first frames'
one-off work (imports, compiled kernels, textures) stay out of it. Prints every run, the median of
each checkout and the ratio.

Then, per frame and in the same run, the steps as each checkout's `benchmarks/bench_render.py
--breakdown-only` times them (world sampling; the render: build, colour, seg/depth, shadows), and
this tree's LiDAR sweep against the bare Embree query of its rays (`benchmarks/bench_lidar.py`).
While a run generates, each worker process's peak and current resident memory (VmHWM, VmRSS)
is read from /proc at the `--warm`-th frame and at every quarter of the run: current memory that
stops growing after the warm frames means no memory is kept from frame to frame (the peak may still
step up where a larger world comes along).

    .venv/bin/python benchmarks/bench_generate.py --base ec11039 [--frames 120] [--rounds 2]
    .venv/bin/python benchmarks/bench_generate.py --frames 1000 --rounds 1 --no-base --no-steps
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
POLL_S = 0.5


@dataclass
class Run:
    """One `testbed generate` run: when each frame's meta appeared, workers' peak memory."""

    label: str
    frames: int
    wall_s: float
    steady_fps: float
    memory_mb: list[tuple[int, list[tuple[float, float]]]] = field(default_factory=list)  # (frames written, per worker (peak, now))


def _children(pid: int) -> list[int]:
    """Every descendant process of `pid` (from /proc)."""
    parent = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(stat.parent.name)] = int(fields[1])
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parent.items() if pp == p]
        out += kids
        todo += kids
    return out


def _worker_memory_mb(pid: int) -> list[tuple[float, float]]:
    """Each pool worker's peak and current resident memory (VmHWM, VmRSS) under `pid` (processes
    started by multiprocessing's spawn), in the order of their process ids."""
    mem = []
    for c in sorted(_children(pid)):
        try:
            cmd = Path(f"/proc/{c}/cmdline").read_bytes()
            status = Path(f"/proc/{c}/status").read_text()
        except OSError:
            continue
        if b"spawn_main" not in cmd:
            continue
        kb = [re.search(rf"{k}:\s+(\d+) kB", status) for k in ("VmHWM", "VmRSS")]
        if all(kb):
            mem.append(tuple(int(m.group(1)) / 1024 for m in kb))
    return mem


def testbed(*args: str) -> list[str]:
    """The testbed command line of the checkout on PYTHONPATH, run with this interpreter."""
    return [sys.executable, "-c", "from testbed.cli import main; main()", *args]


def env_for(checkout: Path) -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(checkout), PYOPENGL_PLATFORM="egl")


def generate_run(checkout: Path, label: str, frames: int, warm: int, scratch: Path) -> Run:
    """`testbed generate` of `frames` urban frames with 2 workers, watched from outside."""
    out = scratch / f"gen-{label}"
    shutil.rmtree(out, ignore_errors=True)
    meta = out / "training" / "meta"
    marks = sorted({warm, *(frames * q // 4 for q in (1, 2, 3))} - {0})
    cmd = testbed("generate", str(checkout / "scenes/urban.yaml"), "--out", str(out),
                  "--frames", str(frames), "--workers", "2")
    log = scratch / f"gen-{label}.log"  # a file, not a pipe: a long run's progress bar fills a pipe
    t0 = time.perf_counter()
    with log.open("w") as err:
        proc = subprocess.Popen(cmd, cwd=checkout, env=env_for(checkout), stdout=subprocess.DEVNULL,
                                stderr=err, text=True)
    memory, last = [], []
    while proc.poll() is None:
        time.sleep(POLL_S)
        last = _worker_memory_mb(proc.pid) or last
        written = len(list(meta.glob("*.json"))) if meta.is_dir() else 0
        while marks and written >= marks[0]:
            memory.append((marks.pop(0), last))
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(f"{label}: `{' '.join(cmd)}` failed:\n{log.read_text()[-3000:]}")
    memory.append((frames, last))
    done = np.sort([p.stat().st_mtime for p in meta.glob("*.json")])
    shutil.rmtree(out)
    steady = (len(done) - warm) / (done[-1] - done[warm - 1])
    return Run(label, frames, wall, steady, memory)


def bench_lines(checkout: Path, script: str, *args: str, pattern: str) -> list[str]:
    """The lines of a checkout's benchmark printout that match `pattern`."""
    res = subprocess.run([sys.executable, str(checkout / "benchmarks" / script), *args],
                         cwd=checkout, env=env_for(checkout), capture_output=True, text=True)
    if res.returncode:
        raise SystemExit(f"{checkout}: {script} failed:\n{res.stderr[-3000:]}")
    return [ln for ln in res.stdout.splitlines() if re.search(pattern, ln)]


def median_ms(lines: list[str], name: str) -> float:
    """The median of a `bench_render.py --breakdown-only` step line."""
    for ln in lines:
        if ln.strip().startswith(name):
            return float(re.search(r"([\d.]+) ms median", ln).group(1))
    raise ValueError(f"no '{name}' line in {lines}")


@contextmanager
def worktree(rev: str):
    """`rev` checked out in a temporary git worktree."""
    path = Path(tempfile.mkdtemp(prefix="bench_base_"))
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-f", str(path), rev],
                   check=True, capture_output=True)
    try:
        yield path
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(path)],
                       capture_output=True)


def print_run(r: Run) -> None:
    mem = "; ".join(f"{n}: {', '.join(f'{hwm:.0f}/{now:.0f}' for hwm, now in workers)}"
                    for n, workers in r.memory_mb)
    print(f"  {r.label:5s} {r.frames} frames in {r.wall_s:6.1f} s; steady {r.steady_fps:.3f} frames/s; "
          f"workers' resident memory MB, peak/now, at frame {mem}", flush=True)


def steps(checkouts: dict[str, Path], frames: int) -> None:
    """World sampling and render per frame for each checkout; the LiDAR against bare Embree."""
    lines = {k: bench_lines(c, "bench_render.py", "--breakdown-only", "--frames", str(frames),
                            pattern=r"^\s+(sample|build|colour|seg|shadows|RENDER)")
             for k, c in checkouts.items()}
    print(f"per frame, median of {frames} urban worlds (bench_render.py --breakdown-only):")
    for name in ("sample", "build", "colour", "seg+depth", "shadows", "RENDER"):
        ms = {k: median_ms(v, name) for k, v in lines.items()}
        ratio = f"  {ms['head'] / ms['base']:.2f}x the base's" if "base" in ms else ""
        print(f"  {name:9s} " + "  ".join(f"{k} {v:7.1f} ms" for k, v in ms.items()) + ratio)
    print("LiDAR sweep against the bare Embree query of its rays (bench_lidar.py, this tree):")
    for ln in bench_lines(checkouts["head"], "bench_lidar.py", "--frames", "1", "--timing-frames", "3",
                          "--repeats", "5",
                          pattern=r"^(one core|\s+wall time|beams|\s*(16|32|64|128) )"):
        print("  " + ln)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", default="ec11039", help="git revision to compare with")
    ap.add_argument("--no-base", action="store_true", help="time this tree only")
    ap.add_argument("--frames", type=int, default=120, help="frames of each run")
    ap.add_argument("--warm", type=int, default=20, help="frames left out of the steady state")
    ap.add_argument("--rounds", type=int, default=2, help="runs of each checkout, alternating")
    ap.add_argument("--step-frames", type=int, default=12, help="worlds of the per-step medians")
    ap.add_argument("--no-steps", action="store_true", help="skip the per-step medians")
    args = ap.parse_args()
    if args.frames <= args.warm:
        ap.error("--frames must exceed --warm")
    with tempfile.TemporaryDirectory(prefix="bench_generate_") as tmp, \
            (worktree(args.base) if not args.no_base else _none()) as base:
        checkouts = {"head": ROOT} if base is None else {"base": base, "head": ROOT}
        print(f"testbed generate scenes/urban.yaml --frames {args.frames} --workers 2; steady state "
              f"after frame {args.warm}; base {args.base if base else '-'}", flush=True)
        runs: dict[str, list[Run]] = {k: [] for k in checkouts}
        for _ in range(args.rounds):
            for label, checkout in checkouts.items():
                runs[label].append(generate_run(checkout, label, args.frames, args.warm, Path(tmp)))
                print_run(runs[label][-1])
        fps = {k: float(np.median([r.steady_fps for r in v])) for k, v in runs.items()}
        print("steady frames/s, median of the rounds: "
              + ", ".join(f"{k} {v:.3f}" for k, v in fps.items())
              + (f"; head / base = {fps['head'] / fps['base']:.2f}x" if "base" in fps else ""))
        if not args.no_steps:
            steps(checkouts, args.step_frames)


@contextmanager
def _none():
    yield None


if __name__ == "__main__":
    main()
