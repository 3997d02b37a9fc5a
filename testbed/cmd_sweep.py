"""`testbed sweep`: many sensor configurations over the same worlds, one table at the end."""

from __future__ import annotations

from pathlib import Path

import click

from .options import with_backend_options


@click.command()
@click.argument("sweep_spec", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(file_okay=False, path_type=Path),
              help="Report folder (default: results/<sweep name>).")
@click.option("--data-dir", "--data", "data_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Folder the sweep writes its datasets, scans and per-point outputs to (default: "
                   "data/sweeps/<name>; --data: its former spelling).")
@click.option("--draws", type=click.IntRange(1),
              help="Bootstrap draws of the frames behind every 95 % interval and paired change "
                   "[default: testbed.uncertainty.DRAWS, 200, which says why and what they cost].")
@with_backend_options
def sweep(sweep_spec: Path, out: Path | None, data_dir: Path | None, draws: int | None, workers: int,
          backend: str, address: str | None) -> None:
    """Run SWEEP_SPEC: re-scan the same worlds for every LiDAR configuration, lift, evaluate, and
    write metrics.csv (every AP with its 95 % interval), paired.csv (each comparison as a paired
    per-object change against its reference point), errors.csv, report.md and plots. A stopped
    sweep resumes.

    SWEEP_SPEC is a sweep spec (scenes/sweeps/*.yaml), not a dataset: it names the scenes, the
    axes and the split."""
    from .backends import make_backend
    from .report import write_report
    from .sweep import SweepSpecError, execute, load_sweep, plan
    from .uncertainty import DRAWS, measure

    try:
        spec = load_sweep(sweep_spec)
    except SweepSpecError as e:
        raise click.ClickException(str(e)) from None
    p = plan(spec, data_dir)
    click.echo(f"sweep '{spec.name}': {len(p.scans)} scan configurations, {len(p.points)} points")
    with make_backend(backend, workers, address) as b:
        results = execute(p, b)
        uncertainty = measure(p, results, b, draws or DRAWS)
    out = out or Path("results") / spec.name
    intro = (f"Sweep spec: `{sweep_spec}`; {len(p.points)} points over {len(spec.scenes)} scene(s): "
             + ", ".join(f"`{s.spec}` (frames {s.frames or 'from spec'}, seed {s.seed if s.seed is not None else 'from spec'})"
                         for s in spec.scenes) + f"; evaluated on the `{spec.split}` split.")
    write_report(results, out, f"Sweep: {spec.name}", intro, uncertainty=uncertainty)
    click.echo(f"wrote {out}/report.md, metrics.csv, paired.csv, errors.csv and plots")
