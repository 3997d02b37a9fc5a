"""`testbed sweep`: many sensor configurations over the same worlds, one table at the end."""

from __future__ import annotations

from pathlib import Path

import click

backend_options = [
    click.option("--workers", default=1, show_default=True, type=click.IntRange(1),
                 help="Parallel jobs (processes for the local backend, CPUs for a local Ray)."),
    click.option("--backend", default="local", show_default=True, type=click.Choice(["local", "ray"])),
    click.option("--address", default=None, help="Ray cluster address (default: a local Ray instance)."),
]


def with_backend_options(fn):
    for opt in reversed(backend_options):
        fn = opt(fn)
    return fn


@click.command()
@click.argument("sweep_spec", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", type=click.Path(file_okay=False, path_type=Path),
              help="Report folder (default: results/<sweep name>).")
@click.option("--data", "data_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Folder for datasets, scans and per-point outputs (default: data/sweeps/<name>).")
@with_backend_options
def sweep(sweep_spec: Path, out: Path | None, data_dir: Path | None, workers: int, backend: str,
          address: str | None) -> None:
    """Run SWEEP_SPEC: re-scan the same worlds for every LiDAR configuration, lift, evaluate, and
    write metrics.csv, errors.csv, report.md and plots. A stopped sweep resumes."""
    from .backends import make_backend
    from .report import write_report
    from .sweep import SweepSpecError, execute, load_sweep, plan

    try:
        spec = load_sweep(sweep_spec)
    except SweepSpecError as e:
        raise click.ClickException(str(e)) from None
    p = plan(spec, data_dir)
    click.echo(f"sweep '{spec.name}': {len(p.scans)} scan configurations, {len(p.points)} points")
    with make_backend(backend, workers, address) as b:
        results = execute(p, b)
    out = out or Path("results") / spec.name
    intro = (f"Sweep spec: `{sweep_spec}`; {len(p.points)} points over {len(spec.scenes)} scene(s): "
             + ", ".join(f"`{s.spec}` (frames {s.frames or 'from spec'}, seed {s.seed if s.seed is not None else 'from spec'})"
                         for s in spec.scenes) + f"; evaluated on the `{spec.split}` split.")
    write_report(results, out, f"Sweep: {spec.name}", intro)
    click.echo(f"wrote {out}/report.md, metrics.csv, errors.csv and plots")
