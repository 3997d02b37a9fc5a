"""`testbed fidelity`: how far a KITTI-format dataset ("sim") is from another ("real") in its LiDAR
scans, images and labels, as one streaming pass per dataset, a table of verdicts and plots.

    stats = compute_stats(root)            # per-frame scalars + fixed-bin histograms
    comp = compare(sim, real, tolerances)  # relative differences and pass/fail verdicts
    write_report(comp, out_dir)            # report.md, fidelity.json, lidar/images/labels.png
"""

from .collect import UnreadableFrame, compute_stats
from .compare import Comparison, Row, ToleranceError, Tolerances, compare, load_tolerances
from .report import write_report
from .stats import DatasetStats

__all__ = ["Comparison", "DatasetStats", "Row", "ToleranceError", "Tolerances", "compare",
           "UnreadableFrame", "compute_stats", "load_tolerances", "write_report"]
