"""One set of numerical kernels on every x86-64 CPU with AVX2 and FMA, so the same spec and seed
give the same output bytes on Intel and AMD, with or without AVX-512.

numpy, OpenBLAS, PyTorch (ATen, oneDNN, MKL), numba, OpenCV and Mesa's llvmpipe each pick their kernels
by the CPU they run on, and kernels of different widths round differently: numpy's float64
sin, cos, exp, log, arctan2 and power run AVX-512 kernels where the CPU has them and others where
it does not, a few ulps apart, enough to move a LiDAR return across an edge and a lifted box
across an IoU threshold. Each library reads its choice from the environment when it loads, so
`pin()` writes the choices below before any of them is imported: `kitti/__init__.py` calls it
first, and every other package of the project imports `kitti` first. Embree takes its cap in
its device config instead (simgen.embree.EMBREE_CONFIG), and the LiDAR recomputes Embree's
ranges (simgen.lidar.kernels.exact_hits). PyTorch's convolutions (oneDNN, NNPACK, MKL) follow the
CPU's caches or vendor, which no setting caps: the networks' reads run their matrix products on
numpy's pinned OpenBLAS instead (`portable_networks`, around every detector and lifter read).

The pins override the user's own settings of these variables (a stale one would silently break
the promise); `TESTBED_NATIVE_KERNELS=1` leaves every library to choose for itself (faster on
some CPUs, no longer the same bytes everywhere). A CPU without AVX2 and FMA is not covered: there
the libraries run what the CPU has and the outputs may differ in their last bits. One case stays
open on covered CPUs: where a LiDAR ray meets two triangles at exactly the same distance (about
one ray in 100,000 on a street, on the diagonal of a flat quad), Embree takes the first it
reaches, and the order it reaches them in could follow its reciprocal's last bits. Such a ray
changes its own return and no other: each ray draws its own random numbers
(simgen.lidar.draws).
"""

from __future__ import annotations

import os
import platform
import sys
import warnings
from contextlib import contextmanager
from functools import partial

NATIVE = "TESTBED_NATIVE_KERNELS"

PINS = {
    # numpy's AVX-512 (X86_V4) loops: float64 sin/cos/exp/log/tan/arc*/arctan2/power and more.
    # Its X86_V3 (AVX2 + FMA) loops stay: every covered CPU runs them.
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    # OpenBLAS (numpy's BLAS) takes kernels and block sizes by core type (Haswell, Zen,
    # SkylakeX...); one type and one thread fix the order of every sum.
    "OPENBLAS_CORETYPE": "Haswell",
    "OPENBLAS_NUM_THREADS": "1",
    # PyTorch: ATen's vectorised kernels, oneDNN's convolutions, MKL's matrix products (the
    # networks' reads take theirs from OpenBLAS instead: portable_networks).
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
def portable_networks():
    """The networks' convolutions and linear layers as matrix products on numpy's OpenBLAS, whose
    kernels and blocking are pinned above (OPENBLAS_CORETYPE, one thread), instead of PyTorch's.
    PyTorch's own are not the same bits everywhere: oneDNN picks its algorithm by the thread
    count and its blocking by the CPU; NNPACK blocks its sums by the CPU's cache sizes; and MKL,
    which ATen's convolutions call, gives other bits on an Intel CPU than on an AMD one even on
    its COMPATIBLE branch (the detector's boxes for one generated frame differed in the printed
    digits under every branch MKL_CBWR names). Gradients and other dtypes keep PyTorch's
    operators. torch is imported here, not with kitti."""
    import torch.nn.functional as F

    conv2d, linear = F.conv2d, F.linear
    F.conv2d = partial(_blas_conv2d, conv2d)
    F.linear = partial(_blas_linear, linear)
    try:
        yield
    finally:
        F.conv2d, F.linear = conv2d, linear


def _plain(torch, *tensors) -> bool:
    """Whether the operator's tensors are float32 on the CPU with no gradient to record."""
    tensors = [t for t in tensors if t is not None]
    grad = torch.is_grad_enabled() and any(t.requires_grad for t in tensors)
    return not grad and all(t.dtype == torch.float32 and t.device.type == "cpu" for t in tensors)


def _pair(v) -> tuple[int, int]:
    return (v, v) if isinstance(v, int) else tuple(v)


def _blas_conv2d(torch_conv2d, x, weight, bias=None, stride=1, padding=0, dilation=1, groups=1):
    """F.conv2d as im2col (ATen's unfold, a copy) and one stacked matrix product per image, the
    groups stacked (numpy.matmul on OpenBLAS); a depthwise one tap by tap (`_depthwise`)."""
    import numpy as np
    import torch
    import torch.nn.functional as F

    if isinstance(padding, str) or x.dim() != 4 or not _plain(torch, x, weight, bias):
        return torch_conv2d(x, weight, bias, stride, padding, dilation, groups)
    (sh, sw), (ph, pw), (dh, dw) = _pair(stride), _pair(padding), _pair(dilation)
    n, c, h, w = x.shape
    o, _, kh, kw = weight.shape
    ho, wo = (h + 2 * ph - dh * (kh - 1) - 1) // sh + 1, (w + 2 * pw - dw * (kw - 1) - 1) // sw + 1
    if groups == c == o:
        out = _depthwise(F.pad(x, (pw, pw, ph, ph)).detach().numpy(), weight.detach().numpy(),
                         (sh, sw), (dh, dw), (ho, wo))
        if bias is not None:
            out += bias.detach().numpy().reshape(1, o, 1, 1)
        return torch.from_numpy(out)
    if (kh, kw, sh, sw, ph, pw) == (1, 1, 1, 1, 0, 0):
        cols = x.contiguous().reshape(n, c, h * w)
    else:
        cols = F.unfold(x, (kh, kw), (dh, dw), (ph, pw), (sh, sw))
    k = c // groups * kh * kw
    wt = weight.detach().contiguous().numpy().reshape(groups, o // groups, k)
    xs = cols.detach().contiguous().numpy().reshape(n, groups, k, ho * wo)
    out = np.empty((n, groups, o // groups, ho * wo), np.float32)
    for i in range(n):
        np.matmul(wt, xs[i], out=out[i])
    if bias is not None:
        out += bias.detach().numpy().reshape(groups, o // groups, 1)
    return torch.from_numpy(out.reshape(n, o, ho, wo))


def _depthwise(xp, weight, stride, dilation, size):
    """A depthwise convolution of the padded input `xp` (N, C, H, W): per tap, in row-major
    order, the strided window times the tap's weight per channel, added in that order (numpy's
    float32 multiply and add, one rounding each). A stack of (1 x k) by (k x L) products per
    channel would cost six times as long."""
    import numpy as np

    (sh, sw), (dh, dw), (ho, wo) = stride, dilation, size
    c, _, kh, kw = weight.shape
    out = np.zeros((xp.shape[0], c, ho, wo), np.float32)
    term = np.empty((c, ho, wo), np.float32)
    taps = [(i * dh, j * dw, weight[:, 0, i, j].reshape(c, 1, 1)) for i in range(kh) for j in range(kw)]
    for image, acc in zip(xp, out):  # one image's planes stay in the cache through the taps
        for y, x, wt in taps:
            np.multiply(image[:, y:y + sh * (ho - 1) + 1:sh, x:x + sw * (wo - 1) + 1:sw], wt, out=term)
            acc += term
    return out


def _blas_linear(torch_linear, x, weight, bias=None):
    """F.linear as one matrix product (numpy.matmul on OpenBLAS)."""
    import torch

    if not _plain(torch, x, weight, bias):
        return torch_linear(x, weight, bias)
    out = x.detach().contiguous().numpy() @ weight.detach().numpy().T
    if bias is not None:
        out += bias.detach().numpy()
    return torch.from_numpy(out)
