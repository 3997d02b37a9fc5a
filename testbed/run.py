"""`testbed run SPEC`, the main job, as a sweep: what it runs and what it adds to the report.

64/32/16 beams x every applicable method x detector and oracle boxes on SPEC's scenes, evaluated
on the `val` split; the report's introduction says so, and a few example frames are drawn.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .sweep import Plan, SweepSpec

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


def run_intro(spec_path: Path, spec: SweepSpec, p: Plan) -> str:
    """The report's first paragraph: what was run, on which split, and where the data lie."""
    return (f"`testbed run {spec_path}`: {len(p.points)} points (methods "
            f"{', '.join(spec.axes.method)}; LiDAR {', '.join(str(b) for b in spec.axes.beams) or 'none'} "
            f"beams; detector and oracle 2D boxes), evaluated on the `val` split. Data under `{p.root}`.")


def add_examples(p: Plan, results, out: Path, n: int) -> list[Path]:
    """Draw `n` example frames into out/examples/ and append them to out/report.md."""
    drawn = draw_examples(p, results, out / "examples", n)
    if drawn:
        with open(out / "report.md", "a") as f:
            f.write("\n## Example frames (truth solid, `fit` 64 beams with detector boxes dashed)\n\n"
                    + "".join(f"![{d.stem}](examples/{d.name})\n\n" for d in drawn))
    return drawn


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
