"""Pipeline stages run through the `testbed` command line, in this process.

The files on disk are the contract between stages (ARCHITECTURE.md), and the command line is the one
interface every stage keeps stable, so a pipeline drives the stages exactly as a user would.
Each stage writes into its own folder and marks it complete with a `.done` file written last, so a
stopped pipeline resumes by skipping what is marked.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
from pathlib import Path

from kitti.io import atomic_write_text


def invoke(*args: object) -> None:
    """Run `testbed ARGS...` in this process; a failing stage raises. The stage's printout (the
    evaluation table of every point, say) is dropped: its files are what the pipeline reads;
    progress bars still show (stderr)."""
    from .cli import cli

    with contextlib.redirect_stdout(io.StringIO()):
        cli.main(args=[str(a) for a in args], prog_name="testbed", standalone_mode=False)


def is_done(folder: Path) -> bool:
    return (folder / ".done").exists()


def mark_done(folder: Path, info: dict) -> None:
    atomic_write_text(folder / ".done", json.dumps(info, sort_keys=True, indent=1) + "\n")


def digest(*parts: object) -> str:
    """Short stable key of a stage's inputs (file contents for paths)."""
    h = hashlib.sha256()
    for p in parts:
        if isinstance(p, Path) and p.is_file():
            h.update(p.read_bytes())
        else:
            h.update(repr(p).encode())
    return h.hexdigest()[:10]


def _options(**values) -> list:
    """`--name value` for every value that is set (None leaves the command's default)."""
    return [a for k, v in values.items() if v is not None for a in (f"--{k.replace('_', '-')}", v)]


def generate(spec: Path, out: Path, frames: int | None, seed: int | None, workers: int) -> Path:
    if not is_done(out):
        invoke("generate", spec, "--out", out, "--workers", workers,
               *_options(frames=frames, seed=seed))
        mark_done(out, {"spec": str(spec), "frames": frames, "seed": seed})
    return out


def detect(data: Path, out: Path, split: str) -> Path:
    if not is_done(out):
        invoke("detect", "--data", data, "--out", out, "--split", split)
        mark_done(out, {"data": str(data), "split": split})
    return out


def rescan(data: Path, out: Path, lidar: str, beams: int | None, max_range: float | None,
           weather=None, workers: int = 1) -> Path:
    """`weather` (fog_extinction, rain_rate attributes) overrides what the LiDAR sees."""
    if not is_done(out):
        invoke("rescan", data, "--out", out, "--lidar", lidar, "--workers", workers,
               *_options(beams=beams, max_range=max_range,
                         fog_extinction=weather and weather.fog_extinction,
                         rain_rate=weather and weather.rain_rate))
        mark_done(out, {"data": str(data), "lidar": lidar, "beams": beams, "max_range": max_range,
                        "weather": None if weather is None else weather.model_dump()})
    return out


def reduce_beams(data: Path, out: Path, beams: int) -> Path:
    if not is_done(out):
        invoke("reduce-beams", "--data", data, "--beams", beams, "--out", out)
        mark_done(out, {"data": str(data), "beams": beams})
    return out


def lift_and_evaluate(data: Path, boxes: str | Path, method: str, split: str, out: Path,
                      range_bins: list[float]) -> dict:
    """Lift the split's 2D boxes to 3D with `method`, evaluate, return the evaluation JSON."""
    result = out / "eval.json"
    if not is_done(out):
        invoke("lift", "--data", data, "--boxes", boxes, "--method", method, "--split", split,
               "--out", out / "pred")
        invoke("evaluate", "--gt", data / "training" / "label_2", "--pred", out / "pred",
               "--split", data / "ImageSets" / f"{split}.txt", "--json", result,
               "--range-bins", ",".join(_fmt_bin(b) for b in range_bins))
        mark_done(out, {"data": str(data), "boxes": str(boxes), "method": method})
    return json.loads(result.read_text())


def _fmt_bin(b: float) -> str:
    return "inf" if b == float("inf") else f"{b:g}"
