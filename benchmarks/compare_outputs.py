"""Are two versions of the testbed byte-identical on every stage's output?

Runs the same small pipeline with the command line of two checkouts (a git revision, checked out in
a temporary worktree, and this working tree by default) and compares every file they write:
generate, rescan (another sensor, and fog), reduce-beams, detect, lift (every method, oracle and
detector boxes), evaluate, and a two-point sweep (`scenes/sweeps/two_point.yaml`) on 2 workers.
A change that only moves code must print "identical"; one meant to change outputs lists what moved.
A PNG file whose bytes moved but whose pixels did not (another row filter or zlib setting) is
listed apart and does not count as a difference.

    .venv/bin/python benchmarks/compare_outputs.py --base a22ef51
    .venv/bin/python benchmarks/compare_outputs.py --base HEAD~3 --head HEAD

Both runs write to the same path (OUT/work) one after the other. Two things are not compared: the
`.done` stage markers (resume bookkeeping that records input paths, which move when a file does),
and the digests in the sweep's cache folder names (`base-`, `scans-`, `points-`, `detections-`:
digests of the generator's and of the detector and lifter code, which change with any edit there;
also where JSON files name those folders).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import kitti  # noqa: F401  (first: it pins the kernels and OpenBLAS's threads before numpy loads)
import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PIXELS = "pixels of "  # key prefix: the digest of a PNG file's decoded pixels
# (name, argv after `testbed`); {W} is the work folder, {S} the golden street of the checkout
PIPELINE = [
    ("generate", ["generate", "{S}", "--out", "{W}/base", "--frames", "4", "--workers", "2"]),
    ("rescan", ["rescan", "--data", "{W}/base", "--out", "{W}/vlp16", "--lidar", "vlp16", "--workers", "2"]),
    ("rescan-fog", ["rescan", "--data", "{W}/base", "--out", "{W}/fog", "--lidar", "hdl64e", "--beams", "16",
                    "--fog-extinction", "0.03", "--workers", "1"]),
    ("reduce-beams", ["reduce-beams", "--data", "{W}/base", "--beams", "16", "--out", "{W}/d16"]),
    ("detect", ["detect", "--data", "{W}/base", "--out", "{W}/det", "--split", "all"]),
    *[(f"lift-{m}-{b}", ["lift", "--data", "{W}/d16" if m != "roadside" else "{W}/base",
                         "--boxes", "gt" if b == "gt" else "{W}/det", "--method", m,
                         "--out", f"{{W}}/lift/{m}-{b}"])
      for m in ("frustum", "fit", "mono", "roadside") for b in ("gt", "det")],
    ("lift-truth", ["lift", "--data", "{W}/base", "--boxes", "gt", "--method", "fit",
                    "--priors", "truth", "--out", "{W}/lift/fit-truth"]),
    ("evaluate", ["evaluate", "--gt", "{W}/base/training/label_2", "--pred", "{W}/lift/fit-gt",
                  "--json", "{W}/eval.json", "--range-bins", "0,20,40,inf"]),
    ("sweep", ["sweep", "scenes/sweeps/two_point.yaml", "--data", "{W}/sweep",
               "--out", "{W}/sweep_report", "--workers", "2"]),
]
DIGEST = re.compile(r"(base|scans|points|detections)-[0-9a-f]{10}(?:-[0-9a-f]{10})?")


def spelled_for(checkout: Path, argv: list[str]) -> list[str]:
    """argv as `checkout`'s command line spells it: before `testbed rescan --data` its dataset was
    an argument."""
    old = 'click.argument("dataset"' in (checkout / "testbed/cmd_rescan.py").read_text()
    if argv[0] != "rescan" or "--data" not in argv or not old:
        return argv
    i = argv.index("--data")
    return [argv[0], argv[i + 1], *argv[1:i], *argv[i + 2:]]


def run_pipeline(checkout: Path, work: Path) -> dict[str, str]:
    """Every stage with `checkout`'s code; returns {relative path: sha256} of what was written,
    plus each stage's printout under 'stdout/<stage>'."""
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    env = dict(os.environ, PYTHONPATH=str(checkout), PYOPENGL_PLATFORM="egl")
    scene = next(p for p in (checkout / "scenes/golden/street.yaml",
                             checkout / "tests/golden/street.yaml") if p.exists())
    out: dict[str, str] = {}
    for name, argv in PIPELINE:
        args = [a.replace("{W}", str(work)).replace("{S}", str(scene)) for a in spelled_for(checkout, argv)]
        cmd = [sys.executable, "-c", "from testbed.cli import main; main()", *args]
        print(f"[{checkout.name}] testbed {' '.join(args)}", flush=True)
        res = subprocess.run(cmd, cwd=checkout, env=env, capture_output=True, text=True)
        if res.returncode:
            raise SystemExit(f"{checkout}: `testbed {' '.join(args)}` failed:\n{res.stderr[-3000:]}")
        out[f"stdout/{name}"] = hashlib.sha256(res.stdout.replace(str(work), "W").encode()).hexdigest()
    for p in sorted(work.rglob("*")):
        if p.is_file() and p.name != ".done":
            rel = DIGEST.sub(r"\1-CODE", str(p.relative_to(work)))
            data = p.read_bytes()
            if p.suffix == ".json":  # provenance (a scan's `source`) names those folders too
                data = DIGEST.sub(r"\1-CODE", data.decode()).encode()
            out[rel] = hashlib.sha256(data).hexdigest()
            if p.suffix == ".png":  # what the file decodes to, whatever the encoder made of it
                img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
                shape = f"{img.shape} {img.dtype}".encode()
                out[PIXELS + rel] = hashlib.sha256(shape + img.tobytes()).hexdigest()
    return out


def worktree(rev: str, where: Path) -> Path:
    path = where / f"rev-{rev.replace('/', '_')}"
    subprocess.run(["git", "worktree", "add", "--detach", str(path), rev], cwd=ROOT, check=True,
                   capture_output=True)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare against")
    ap.add_argument("--head", default=None, help="git revision [default: this working tree]")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "compare_outputs")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="compare-"))
    trees = []
    try:
        base = worktree(args.base, tmp)
        trees.append(base)
        head = worktree(args.head, tmp) if args.head else ROOT
        if args.head:
            trees.append(head)
        work = args.out.resolve() / "work"  # the stages run in each checkout's folder
        a = run_pipeline(base, work)
        b = run_pipeline(head, work)
    finally:
        for t in trees:
            subprocess.run(["git", "worktree", "remove", "--force", str(t)], cwd=ROOT,
                           capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)
    only_a, only_b = (sorted(k for k in x.keys() - y.keys() if not k.startswith(PIXELS))
                      for x, y in ((a, b), (b, a)))
    changed = sorted(k for k in a.keys() & b.keys() if a[k] != b[k] and not k.startswith(PIXELS))
    encoded = [k for k in changed if a.get(PIXELS + k, "a") == b.get(PIXELS + k, "b")]
    differ = [k for k in changed if k not in encoded]
    files = sum(not k.startswith(PIXELS) for k in a), sum(not k.startswith(PIXELS) for k in b)
    print(f"{files[0]} outputs of {args.base} vs {files[1]} of {args.head or 'the working tree'}")
    for label, keys in (("only in base", only_a), ("only in head", only_b), ("differ", differ),
                        ("same pixels, encoded otherwise", encoded)):
        for k in keys:
            print(f"  {label}: {k}")
    if only_a or only_b or differ:
        raise SystemExit(1)
    print("identical" if not encoded else f"identical but for the encoding of {len(encoded)} PNG files "
          "(each decodes to the same pixels)")


if __name__ == "__main__":
    main()
