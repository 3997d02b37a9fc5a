"""`testbed run SPEC`: the main job, end to end on one scene spec."""

from __future__ import annotations

import time
from pathlib import Path

import click

from .options import with_backend_options


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
    metrics.csv (every AP with its 95 % interval), paired.csv, errors.csv, plots and example frames.

    SPEC is a scene spec (scenes/*.yaml), not a dataset; the split evaluated is the scenes' `val`."""
    from .backends import make_backend
    from .report import write_report
    from .run import add_examples, run_intro, run_spec
    from .sweep import execute, plan
    from .uncertainty import DRAWS, measure

    t0 = time.perf_counter()
    spec = run_spec(spec_path, frames, seed)
    p = plan(spec)
    with make_backend(backend, workers, address) as b:
        results = execute(p, b)
        uncertainty = measure(p, results, b, DRAWS)
    out = out or Path("results") / spec.name
    intro = run_intro(spec_path, spec, p)
    write_report(results, out, f"Testbed run: {spec.name}", intro, uncertainty=uncertainty)
    add_examples(p, results, out, examples)
    click.echo(f"wrote {out}/report.md in {time.perf_counter() - t0:.0f} s")
