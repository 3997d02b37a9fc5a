"""The official KITTI object evaluation (2D, bird's-eye, 3D, AOS; R11 and R40), exact and CPU-only,
plus the breakdowns a sensitivity study needs: AP per distance bin, matched-pair errors and the
volumetric metrics of the tolling thesis."""

from .annotations import load_annotations
from .evaluate import ap_2d, evaluate
from .folders import evaluate_folders
from .report import EvalResult

__all__ = ["EvalResult", "ap_2d", "evaluate", "evaluate_folders", "load_annotations"]
