"""One set of numerical kernels on every x86-64 CPU with AVX2 and FMA, so the same spec and seed
give the same output bytes on Intel and AMD, with or without AVX-512.

numpy, OpenBLAS, PyTorch (ATen, oneDNN, MKL), numba, OpenCV and Mesa's llvmpipe each pick their kernels
by the CPU they run on, and kernels of different widths round differently: numpy's float64
sin, cos, exp, log, arctan2 and power run AVX-512 kernels where the CPU has them and others where
it does not, a few ulps apart, enough to move a LiDAR return across an edge and a lifted box
across an IoU threshold. Each library reads its choice from the environment when it loads, so
`pin()` writes the choices below before any of them is imported: `kitti/__init__.py` calls it
first, and every other package of the project imports `kitti` first. Embree takes its cap in
its device config instead (simgen.embree.EMBREE_CONFIG). PyTorch's oneDNN and NNPACK convolutions
size their blocks by the CPU's caches, which no setting caps: the networks run ATen's own
convolutions on MKL instead (`aten_convolutions`, around every detector and lifter read).

The pins override the user's own settings of these variables (a stale one would silently break
the promise); `TESTBED_NATIVE_KERNELS=1` leaves every library to choose for itself (faster on
some CPUs, no longer the same bytes everywhere). A CPU without AVX2 and FMA is not covered: there
the libraries run what the CPU has and the outputs may differ in their last bits.
"""

from __future__ import annotations

import os
import platform
import sys
import warnings
from contextlib import contextmanager

NATIVE = "TESTBED_NATIVE_KERNELS"

PINS = {
    # numpy's AVX-512 (X86_V4) loops: float64 sin/cos/exp/log/tan/arc*/arctan2/power and more.
    # Its X86_V3 (AVX2 + FMA) loops stay: every covered CPU runs them.
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    # OpenBLAS (numpy's BLAS) takes kernels and block sizes by core type (Haswell, Zen,
    # SkylakeX...); one type and one thread fix the order of every sum.
    "OPENBLAS_CORETYPE": "Haswell",
    "OPENBLAS_NUM_THREADS": "1",
    # PyTorch: ATen's vectorised kernels, oneDNN's convolutions, MKL's matrix products. MKL's
    # COMPATIBLE branch is the one its vendor promises to be the same on Intel and AMD.
    "ATEN_CPU_CAPABILITY": "avx2",
    "ONEDNN_MAX_CPU_ISA": "AVX2",
    "MKL_CBWR": "COMPATIBLE",
    "MKL_DYNAMIC": "FALSE",
    "OMP_DYNAMIC": "FALSE",
    # numba: code for the generic x86-64 target rather than the host's (its cache is kept by
    # target), and no Intel SVML vector maths (it would replace libm's calls where installed).
    "NUMBA_CPU_NAME": "generic",
    "NUMBA_DISABLE_INTEL_SVML": "1",
    # Mesa's llvmpipe (the camera without a GPU): 256-bit vectors, not the CPU's widest.
    "LP_NATIVE_VECTOR_WIDTH": "256",
}


# OpenCV's AVX-512 kernels (its build dispatches up to AVX512-SKX); named only where the CPU
# has AVX-512, since OpenCV warns at every import about disabling a feature the CPU lacks.
OPENCV_AVX512 = {"OPENCV_CPU_DISABLE": "AVX512-SKX"}


def cpu_flags() -> set[str]:
    """The CPU's feature flags as Linux lists them; empty where they cannot be read."""
    try:
        with open("/proc/cpuinfo") as f:
            return set(next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), []))
    except OSError:
        return set()


def covered() -> bool:
    """Whether this CPU is one the promise covers: x86-64 with AVX2 and FMA."""
    return platform.machine().lower() in ("x86_64", "amd64") and {"avx2", "fma"} <= cpu_flags()


def pins() -> dict[str, str]:
    """The settings this process runs under: PINS (and OpenCV's on a CPU with AVX-512), or none
    where the user asked for native kernels or the CPU is not covered. What a worker on another
    host needs in its environment."""
    if os.environ.get(NATIVE, "") not in ("", "0") or not covered():
        return {}
    return {**PINS, **(OPENCV_AVX512 if "avx512f" in cpu_flags() else {})}


def pin() -> dict[str, str]:
    """Write `pins()` into the environment (inherited by worker processes) and return them.
    Warns when numpy was loaded before they could reach it."""
    written = pins()
    os.environ.update(written)
    numpy = sys.modules.get("numpy")
    if written and numpy is not None and _avx512_enabled(numpy):
        warnings.warn("numpy was imported before the testbed could pin its kernels: its AVX-512 "
                      "loops stay on, and outputs may differ in their last bits from other machines' "
                      "(import kitti, simgen, detector, lifter or testbed before numpy)", stacklevel=3)
    return written


def _avx512_enabled(numpy) -> bool:
    features = getattr(getattr(numpy, "_core", None), "_multiarray_umath", None)
    return bool(getattr(features, "__cpu_features__", {}).get("X86_V4"))


@contextmanager
def aten_convolutions():
    """PyTorch's convolutions by ATen on MKL's COMPATIBLE branch (pinned above) rather than oneDNN
    or NNPACK. oneDNN picks its algorithm by the thread count (one and two threads give other
    bits) and its blocking by the CPU; NNPACK, which ATen takes for a batch of 16 or more (a
    detector batch of 8 images with their mirrors, a lifter frame's 8 crops with theirs), blocks
    its sums by the CPU's cache sizes (an AVX-512 EPYC and an AVX2 one differ in the last bits).
    The same bits on Intel and AMD and with 1 or 2 threads (tests/test_same_bytes.py), at the
    same speed for the project's networks. torch is imported here, not with kitti."""
    import torch

    before = torch.backends.mkldnn.enabled
    torch.backends.mkldnn.enabled = False
    try:
        with torch.backends.nnpack.flags(enabled=False):
            yield
    finally:
        torch.backends.mkldnn.enabled = before
