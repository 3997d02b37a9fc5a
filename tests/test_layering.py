"""The packages' one-way flow, read from the import graph of every module (imports inside
functions included): scenes -> simgen -> KITTI files -> detector / lifter -> kitti.eval -> testbed.

The command line loads a stage's heavy dependencies only when that stage runs.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("kitti", "simgen", "detector", "lifter", "fidelity", "testbed")
MAY_IMPORT = {"kitti": {"kitti"}, "simgen": {"kitti", "simgen"}, "detector": {"kitti", "detector"},
              "lifter": {"kitti", "lifter"}, "fidelity": {"kitti", "lifter", "fidelity"},
              "testbed": set(PACKAGES)}
HEAVY = ("torch", "trimesh", "embreex", "pyrender", "numba")
REAL_KITTI = ROOT.parent / "shared" / "kitti_real_dev"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, module: str) -> set[str]:
    """Every project module that `path` imports, anywhere in the file."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            found.add(base)
            found |= {f"{base}.{a.name}" for a in node.names}  # `from . import meta`
    return {m for m in found if m.split(".")[0] in PACKAGES}


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    files = {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}
    return {m: {i for i in _imports(p, m) if i in files and i != m} for m, p in files.items()}


def test_every_package_imports_only_what_its_layer_may(graph):
    assert len(graph) > 80  # every module of the five packages was read
    wrong = [(m, i) for m, deps in graph.items() for i in deps
             if i.split(".")[0] not in MAY_IMPORT[m.split(".")[0]]]
    assert wrong == []


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Import cycles (depth-first); a package's __init__ importing its own modules, or a module
    importing its package, is the package, not a cycle."""
    def deps(m: str) -> set[str]:
        return {i for i in graph.get(m, ()) if not (m == i.rsplit(".", 1)[0] or i == m.rsplit(".", 1)[0])}

    state: dict[str, int] = {}
    cycles = []

    def visit(m: str, stack: list[str]) -> None:
        state[m] = 1
        for i in sorted(deps(m)):
            if state.get(i) == 1:
                cycles.append(stack[stack.index(i):] + [m, i] if i in stack else [m, i])
            elif i not in state:
                visit(i, stack + [m])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    return cycles


def test_the_cycle_check_finds_cycles_and_passes_packages():
    assert _cycles({"a.x": {"a.y"}, "a.y": {"a.z"}, "a.z": {"a.x"}}) == [["a.x", "a.y", "a.z", "a.x"]]
    assert _cycles({"a": {"a.x"}, "a.x": {"a"}}) == []


def test_no_import_cycle_between_modules(graph):
    assert _cycles(graph) == []


def _imported_modules(args: list[str]) -> set[str]:
    """Top-level names of every module `testbed ARGS` imports (python -X importtime)."""
    res = subprocess.run([sys.executable, "-X", "importtime", "-c",
                          "from testbed.cli import main; main()", *args],
                         cwd=ROOT, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    names = {line.split("|")[-1].strip().split(".")[0] for line in res.stderr.splitlines()
             if line.startswith("import time:")}
    assert "click" in names  # the report was read
    return names


def test_help_loads_no_heavy_dependency():
    """`kitti` itself loads (every package imports it first, for its CPU pins), none of its
    modules' dependencies."""
    assert not _imported_modules(["--help"]) & {*HEAVY, "numpy", "pydantic"}


@pytest.mark.skipif(not REAL_KITTI.is_dir(), reason=f"real KITTI dev frames not found at {REAL_KITTI}")
def test_reduce_beams_on_real_kitti_never_loads_the_simulator(tmp_path):
    names = _imported_modules(["reduce-beams", "--data", str(REAL_KITTI), "--beams", "32",
                               "--out", str(tmp_path / "r32"), "--workers", "1"])
    assert not names & {"simgen", "trimesh", "embreex", "pyrender", "torch"}
    assert len(list((tmp_path / "r32" / "training" / "velodyne").glob("*.bin"))) == 11


NUMERIC = ("numpy", "torch", "cv2", "scipy", "numba", "embreex", "trimesh", "pyrender", "shapely")


def _first_imports(path: Path) -> list[str]:
    """The top-level names a file's module-level imports load, in order (`__future__` left out)."""
    names = []
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            names += [a.name.split(".")[0] for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            names.append("." if node.level else (node.module or "").split(".")[0])
    return names


@pytest.mark.parametrize("path", [ROOT / p / "__init__.py" for p in PACKAGES if p != "kitti"]
                         + sorted((ROOT / "benchmarks").glob("*.py")), ids=lambda p: p.parent.name + "/" + p.name)
def test_kitti_pins_the_kernels_before_any_numerical_library_loads(path):
    """numpy, torch and the rest read the kernel pins (kitti.cpu) once, when they load: a file
    that loads one before a project package runs AVX-512 loops on a CPU that has them, and its
    figures differ in the last bits from other machines'."""
    names = _first_imports(path)
    project = next((i for i, n in enumerate(names) if n in PACKAGES), len(names))
    numeric = next((i for i, n in enumerate(names) if n in NUMERIC), len(names))
    assert project <= numeric, f"{path.name} loads {names[numeric]} first"
