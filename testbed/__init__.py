"""The command line, pipelines, sweeps, execution backends and reports."""

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy, numba or torch loads)
