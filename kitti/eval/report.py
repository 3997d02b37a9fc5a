"""The result of an evaluation: AP tables, breakdowns, the familiar printout and the JSON."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from .ap import capped, devkit_cap
from .protocol import min_overlap

_LABEL = {"2d": "bbox", "bev": "bev ", "3d": "3d  ", "aos": "aos "}


def _fmt(v) -> str:
    return "  -  " if v is None else f"{v:.2f}"


def _finite(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


@dataclass
class EvalResult:
    """AP as `{class: {metric: {"R11": [easy, moderate, hard], "R40": [...]}}}`.

    `ap` uses the strict IoU thresholds (0.7/0.5/0.5), `ap_loose` the loose ones for bird's-eye and
    3D (0.5/0.25/0.25). A metric that cannot be computed is absent from the dict and listed in
    `absent` with the reason (AOS without alpha, bird's-eye/3D without 3D boxes).
    """

    classes: list[str]
    ap: dict
    ap_loose: dict
    n_gt: dict  # {class: [easy, moderate, hard]} evaluated truth boxes
    recall: dict  # {class: {metric: [e, m, h]}} recall with every detection (strict IoU)
    precision: dict  # {class: {metric: {difficulty: [41 monotone precisions]}}} (strict)
    absent: dict = field(default_factory=dict)  # {class: {metric: reason}}
    range_bins: dict | None = None
    errors: dict = field(default_factory=dict)
    volumetric: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    # {class: {"strict": {metric: [e, m, h]}, "loose": {...}}}: AP|R40 on the measured recall
    # (kitti.eval.ap: the devkit's AP|R40 is capped at (n - 1) / 40 up to 40 truth boxes)
    measured: dict = field(default_factory=dict)

    def capped(self, cls: str) -> bool:
        """Whether some difficulty of `cls` holds fewer truth boxes than the devkit's AP|R40 needs
        to reach 100 (and more than none)."""
        return any(capped(n) for n in self.n_gt.get(cls, []))

    def to_json(self) -> dict:
        """Strict JSON: a non-finite number (an open-ended bin edge such as inf) becomes null."""
        return _finite({"ap": self.ap, "ap_loose": self.ap_loose, "n_gt": self.n_gt, "recall": self.recall,
                "absent": self.absent, "range_bins": self.range_bins, "errors": self.errors,
                "volumetric": self.volumetric, "precision": self.precision,
                "settings": self.settings, "ap_r40_measured_recall": self.measured})

    def table(self) -> str:
        """The printout of the popular Python port of the devkit, R11 ("AP") then R40 blocks."""
        lines = []
        for cls in self.classes:
            strict = [min_overlap(cls, m) for m in ("2d", "bev", "3d")]
            loose = [min_overlap(cls, m, loose=True) for m in ("2d", "bev", "3d")]
            for ap, ovs in ((self.ap[cls], strict), (self.ap_loose[cls], loose)):
                for key, name in (("R11", "AP"), ("R40", "AP_R40")):
                    lines.append(f"{cls} {name}@{ovs[0]:.2f}, {ovs[1]:.2f}, {ovs[2]:.2f}:")
                    for m in ("2d", "bev", "3d", "aos"):
                        if m in ap:
                            lines.append(f"{_LABEL[m]} AP:" + ", ".join(_fmt(v) for v in ap[m][key]))
            if self.capped(cls) and cls in self.measured:
                lines += self._measured_lines(cls, strict, loose)
            for m, why in self.absent.get(cls, {}).items():
                lines.append(f"({cls} {m}: not evaluated, {why})")
        if self.range_bins:
            lines += self._range_lines()
        for how, per_class in self.errors.items():
            lines.append("")
            lines.append(f"Matched-pair errors ({how}; mean |error|, metres / degrees)")
            lines.append(f"{'class':<11}{'range m':>10}{'n':>7}{'centre':>8}{'depth':>8}{'h':>7}{'w':>7}"
                         f"{'l':>7}{'yaw':>7}{'yaw%pi':>8}")
            for cls, d in per_class.items():
                rows = [("all", d["all"])] + [(f"{b['range'][0]:g}-{b['range'][1]:g}", b)
                                              for b in d.get("bins", [])]
                for label, s in rows:
                    lines.append(f"{cls:<11}{label:>10}{s['n']:>7}{_fmt(s['centre']['mean']):>8}"
                                 f"{_fmt(s['depth']['mean']):>8}{_fmt(s['h']['mean']):>7}"
                                 f"{_fmt(s['w']['mean']):>7}{_fmt(s['l']['mean']):>7}"
                                 f"{_fmt(s['yaw_deg']['mean']):>7}{_fmt(s['yaw_mod_pi_deg']['mean']):>8}")
        for how, per_class in self.volumetric.items():
            lines.append("")
            lines.append(f"Volumetric metrics (004; {how} pairs; D = {self.settings.get('max_distance')} m)")
            lines.append(f"{'class':<11}{'n':>7}{'P_dim%':>8}{'P_loc%':>8}{'E_dim':>7}{'E_loc':>7}"
                         + "".join(f"{k:>6}" for k in ("L", "W", "H", "XC", "YC", "ZC")))
            for cls, v in per_class.items():
                v = v["all"]
                lines.append(f"{cls:<11}{v['n']:>7}{_fmt(v['size_precision']):>8}"
                             f"{_fmt(v['location_precision']):>8}{_fmt(v['size_error']):>7}"
                             f"{_fmt(v['location_error']):>7}"
                             + "".join(f"{_fmt(v[k]):>6}" for k in ("L", "W", "H", "XC", "YC", "ZC")))
        return "\n".join(lines) + "\n"

    def _range_lines(self) -> list[str]:
        """AP_R40 (moderate) per distance bin, the devkit's; and on the measured recall when a bin
        holds 40 or fewer truth boxes (`capped`), as bins mostly do."""
        bins = self.range_bins["bins"]
        metrics = [m for m in ("2d", "bev", "3d", "aos")
                   if any(m in b["ap"].get(c, {}) for b in bins for c in self.classes)]
        head = f"{'class':<11}{'range m':>10}{'n_gt':>7}" + "".join(f"{m:>8}" for m in metrics)
        few = any(capped(b["n_gt"][c][1]) for b in bins for c in self.classes)
        blocks = [("the devkit's", lambda b, cls, m: b["ap"][cls].get(m, {}).get("R40", [None] * 3)[1])]
        if few:
            blocks.append(("on the measured recall, as bins of 40 or fewer truth boxes cap the devkit's",
                           lambda b, cls, m: b["ap_r40_measured"][cls].get(m, [None] * 3)[1]))
        lines = []
        for what, value in blocks:
            lines += ["", f"AP_R40 by distance, {what} (moderate; truth and detections outside a bin "
                      "ignored)", head]
            for cls in self.classes:
                for b in bins:
                    lo, hi = b["range"]
                    lines.append(f"{cls:<11}{f'{lo:g}-{hi:g}':>10}{b['n_gt'][cls][1]:>7}"
                                 + "".join(f"{_fmt(value(b, cls, m)):>8}" for m in metrics))
        return lines

    def _measured_lines(self, cls: str, strict: list[float], loose: list[float]) -> list[str]:
        n = self.n_gt[cls]
        caps = ", ".join(f"{devkit_cap(k):.2f}" for k in n)
        lines = [f"({cls}: {n[0]} / {n[1]} / {n[2]} truth boxes, easy / moderate / hard: the devkit's "
                 f"AP_R40 above cannot exceed {caps}; on the measured recall:)"]
        for blocks, ovs in ((self.measured[cls]["strict"], strict), (self.measured[cls]["loose"], loose)):
            if not blocks:
                continue
            lines.append(f"{cls} AP_R40@{ovs[0]:.2f}, {ovs[1]:.2f}, {ovs[2]:.2f} on the measured recall:")
            for m in ("2d", "bev", "3d", "aos"):
                if m in blocks:
                    lines.append(f"{_LABEL[m]} AP:" + ", ".join(_fmt(v) for v in blocks[m]))
        return lines
