"""The lifter: 2D boxes plus LiDAR (or the image alone) to 3D boxes."""

import os

# PyTorch picks its CPU kernels by the CPU (ATen's DEFAULT / AVX2 / AVX512, oneDNN's up to AVX-512),
# and kernels of different widths round differently: eight frames' detections hashed with ATen on
# DEFAULT or oneDNN capped at SSE4.1 differ from AVX2's. Both are read at the first tensor operation,
# so capping them here, before any, gives the same outputs on every x86-64 CPU from AVX2 up (the
# LiDAR's Embree kernels are capped alike: simgen.shadows.EMBREE_CONFIG). A user's own setting wins.
os.environ.setdefault("ATEN_CPU_CAPABILITY", "avx2")
os.environ.setdefault("ONEDNN_MAX_CPU_ISA", "AVX2")
