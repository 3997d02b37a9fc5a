"""The lifter: 2D boxes plus LiDAR (or the image alone) to 3D boxes."""

import os

# PyTorch's CPU kernels capped at AVX2 before any tensor operation, as detector/__init__.py does
# (why: there); the two packages import neither each other nor a shared module of their own.
os.environ.setdefault("ATEN_CPU_CAPABILITY", "avx2")
os.environ.setdefault("ONEDNN_MAX_CPU_ISA", "AVX2")
