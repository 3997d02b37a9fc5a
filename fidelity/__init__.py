"""How far a KITTI-format dataset ("sim") is from another ("real") in its LiDAR scans, images and
labels, as one streaming pass per dataset, a table of verdicts and plots; `testbed fidelity` wraps
it. It reads any two KITTI-format roots and depends on `kitti` and on the lifter's road and ground
fitting from a scan (`lifter.ground`, `lifter.road`), never on the simulator.

    stats = compute_stats(root)            # per-frame scalars + fixed-bin histograms
    comp = compare(sim, real, tolerances)  # relative differences and pass/fail verdicts
    write_report(comp, out_dir)            # report.md, fidelity.json, lidar/images/labels.png
"""

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy loads)

from .collect import UnreadableFrame, compute_stats
from .compare import Comparison, Row, ToleranceError, Tolerances, compare, load_tolerances
from .report import write_report
from .stats import DatasetStats

__all__ = ["Comparison", "DatasetStats", "Row", "ToleranceError", "Tolerances", "compare",
           "UnreadableFrame", "compute_stats", "load_tolerances", "write_report"]
