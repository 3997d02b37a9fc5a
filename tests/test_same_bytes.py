"""The same output bytes on every covered CPU (kitti.cpu): the small scene of testbed.fingerprint
run through generate, rescan, detect, lift and evaluate must write exactly the files of the
committed manifest, with any worker or thread count and whatever the user's environment asks of
the numerical libraries; a machine that differs fails here, naming the first file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from kitti.cpu import NATIVE, PINS, covered
from testbed.fingerprint import MANIFEST, first_difference, manifest, read_manifest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(not covered(),
                                reason="the same-bytes promise covers x86-64 with AVX2 and FMA")

# Every setting the project's dependencies read to choose their kernels, each pointed away from
# the pins: numpy's loops below AVX2, OpenBLAS's Sandy Bridge kernels on two threads, ATen's
# scalar kernels, oneDNN on SSE4.1, MKL's own choice, numba for the host, llvmpipe's 128-bit
# vectors. The pins override each of them, so the bytes must not move.
ELSEWHERE = {"NPY_DISABLE_CPU_FEATURES": "X86_V3", "OPENBLAS_CORETYPE": "Sandybridge",
             "OPENBLAS_NUM_THREADS": "2", "ATEN_CPU_CAPABILITY": "default",
             "ONEDNN_MAX_CPU_ISA": "SSE41", "MKL_CBWR": "AUTO", "NUMBA_CPU_NAME": "host",
             "LP_NATIVE_VECTOR_WIDTH": "128"}


def _environment(extra: dict[str, str]) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in PINS and k != NATIVE}
    return {**env, "PYOPENGL_PLATFORM": "egl", **extra}


def _run(code: str, extra: dict[str, str]) -> str:
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=_environment(extra),
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.strip()


def _chain(root: Path, workers: int, threads: int, extra: dict[str, str]) -> dict[str, str]:
    _run(f"from pathlib import Path; from testbed.fingerprint import run_chain; "
         f"run_chain(Path({str(root)!r}), {workers}, {threads})", extra)
    return manifest(root)


def test_the_small_scene_gives_the_committed_bytes_under_every_setting(tmp_path):
    expected = read_manifest(MANIFEST)
    plain = _chain(tmp_path / "plain", 1, 1, {})
    assert first_difference(plain, expected) is None, f"the outputs here differ from {MANIFEST}"
    other = _chain(tmp_path / "other", 2, 2, ELSEWHERE)
    assert first_difference(other, expected) is None, "2 workers, 2 threads, other kernels asked for"


PROBE = ("import kitti, numpy, torch; from numpy.lib.introspect import opt_func_info; "
         "loops = {v['current'] for f in opt_func_info(signature='float64.*').values() for v in f.values()}; "
         "print(torch.backends.cpu.get_cpu_capability(), any('X86_V4' in c for c in loops))")


def test_the_pins_override_the_users_settings():
    assert _run(PROBE, ELSEWHERE) == "AVX2 False"


def test_native_kernels_leave_the_libraries_to_choose():
    """The escape hatch works, so the test above is not passing for want of a setting that bites."""
    assert _run(PROBE, {**ELSEWHERE, NATIVE: "1"}).split()[0] == "DEFAULT"
    assert _run("import os, kitti; print(os.environ.get('MKL_CBWR'))", {NATIVE: "1"}) == "None"


READ = ("import os, kitti; os.environ['MKL_CBWR'] = {branch!r}; import hashlib, torch; "
        "from detector.infer import Detector; from kitti.cpu import portable_networks; "
        "torch.manual_seed(0); x = torch.rand(2, 3, 64, 96); model = Detector.load(None).models[0]; "
        "ctx = portable_networks(); ctx.__enter__(); out = model.predict_raw(x); "
        "print(hashlib.sha256(out.detach().numpy().tobytes()).hexdigest())")


def test_the_detector_s_read_does_not_follow_mkl_s_branch():
    """MKL gives other bits on Intel than on AMD on every branch it offers (kitti.cpu); the
    branches it runs on any covered CPU stand in for the vendors: the read must not move."""
    reads = {_run(READ.format(branch=b), {}) for b in ("COMPATIBLE", "SSE4_2", "AVX2")}
    assert len(reads) == 1


def test_first_difference_names_the_first_file_in_path_order():
    expected = {"a/1": "0" * 64, "b/2": "1" * 64}
    assert first_difference(dict(expected), expected) is None
    assert first_difference({"a/1": "0" * 64, "b/2": "2" * 64}, expected).startswith("b/2: sha256")
    assert first_difference({"b/2": "1" * 64}, expected) == "a/1: expected, not written"
    assert first_difference({**expected, "a/0": "3" * 64}, expected) == "a/0: written, not in the manifest"
