"""`testbed run SPEC`: the main job, end to end on one scene spec."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from .cmd_sweep import with_backend_options

if TYPE_CHECKING:
    from .sweep import SweepSpec

RUN_BEAMS = [64, 32, 16]


def run_spec(spec_path: Path, frames: int | None, seed: int | None) -> SweepSpec:
    """The main job as a sweep: 64/32/16 beams x every applicable method x detector and oracle boxes."""
    from lifter.methods import METHODS
    from simgen.spec import load_spec

    from .sweep import Axes, SceneRef, SweepSpec

    scene = load_spec(spec_path)
    has_lidar = scene.lidar is not None
    methods = [m.name for m in METHODS.values() if (has_lidar or not m.needs_scan)
               and (m.rig == "any" or scene.rig.type == "gantry")]
    axes = Axes(lidar=[scene.lidar.preset] if has_lidar else [], beams=RUN_BEAMS if has_lidar else [],
                max_range=[scene.lidar.max_range] if has_lidar else [None],
                method=methods, boxes=["detector", "gt"])
    return SweepSpec(name=scene.name, scenes=[SceneRef(spec=spec_path, frames=frames, seed=seed)],
                     axes=axes, split="val", data_dir=Path("data/runs"))


@click.command()
@click.argument("spec_path", metavar="SPEC", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(file_okay=False, path_type=Path),
              help="Report folder (default: results/<spec name>).")
@click.option("--frames", type=click.IntRange(min=1), help="Frames to generate [default: the spec's].")
@click.option("--seed", type=click.IntRange(min=0), help="Seed [default: the spec's].")
@click.option("--examples", default=3, show_default=True, type=click.IntRange(0),
              help="Example frames drawn with truth and predictions.")
@with_backend_options
def run(spec_path: Path, out: Path | None, frames: int | None, seed: int | None, examples: int,
        workers: int, backend: str, address: str | None) -> None:
    """Generate SPEC's scenes (cached by spec and seed), detect with the shipped weights, re-scan with
    64, 32 and 16 beams, lift with each method, evaluate, and write results/<name>/: report.md,
    metrics.csv, errors.csv, plots and example frames."""
    from .backends import make_backend
    from .report import write_report
    from .sweep import execute, plan

    t0 = time.perf_counter()
    spec = run_spec(spec_path, frames, seed)
    p = plan(spec)
    with make_backend(backend, workers, address) as b:
        results = execute(p, b)
    out = out or Path("results") / spec.name
    intro = (f"`testbed run {spec_path}`: {len(p.points)} points (methods "
             f"{', '.join(spec.axes.method)}; LiDAR {', '.join(str(b) for b in spec.axes.beams) or 'none'} "
             f"beams; detector and oracle 2D boxes), evaluated on the `val` split. Data under `{p.root}`.")
    write_report(results, out, f"Testbed run: {spec.name}", intro)
    drawn = draw_examples(p, results, out / "examples", examples)
    if drawn:
        with open(out / "report.md", "a") as f:
            f.write("\n## Example frames (truth solid, `fit` 64 beams with detector boxes dashed)\n\n"
                    + "".join(f"![{d.stem}](examples/{d.name})\n\n" for d in drawn))
    click.echo(f"wrote {out}/report.md in {time.perf_counter() - t0:.0f} s")


def draw_examples(p, results, folder: Path, n: int) -> list[Path]:
    """A few validation frames with the truth and one method's predictions, image and bird's-eye."""
    from kitti.dataset import KittiDataset
    from kitti.io import atomic_path

    from .draw import MIN_SCORE, draw_frame, plt
    from .stages import is_done
    from .sweep import generator_key, models_key

    chosen = None
    for pt, _ in results:  # prefer fit on 64 beams with detector boxes, else the first point
        if pt.method == "fit" and pt.boxes == "detector" and pt.scan and pt.scan.beams == 64:
            chosen = pt
            break
    chosen = chosen or (results[0][0] if results else None)
    if chosen is None or n == 0:
        return []
    generator = generator_key()
    data = (p.scan_dir(chosen.scene, generator, chosen.scan) if chosen.scan
            else p.base_dir(chosen.scene, generator))
    point_dir = p.points_dir(f"{generator}-{models_key()}") / chosen.key
    pred = point_dir / "pred"
    if not is_done(point_dir):
        return []
    ds = KittiDataset(data)
    ids = ds.ids(p.spec.split)[:n]
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("frame_*.png"):  # pictures of an earlier run's frames
        old.unlink()
    drawn = []
    for fid in ids:
        fig = draw_frame(ds, fid, pred, title=f"frame {fid}: truth solid, {chosen.method} "
                         f"({chosen.scan.key if chosen.scan else 'no LiDAR'}, {chosen.boxes} boxes, "
                         f"score >= {MIN_SCORE:g}) dashed")
        path = folder / f"frame_{fid}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", bbox_inches="tight")
        plt.close(fig)
        drawn.append(path)
    return drawn
