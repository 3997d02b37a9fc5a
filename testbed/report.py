"""Sweep and run reports: one long CSV of every number, a Markdown summary and plots.

Input is the evaluation JSON of each point (`kitti.eval`, as `testbed evaluate --json` writes it) (keys `ap`, `range_bins`, `errors`);
nothing is recomputed here, so a report can be rebuilt from a finished sweep at any time.
"""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from kitti.eval.protocol import DIFFICULTIES as DIFFS  # noqa: E402
from kitti.io import atomic_path, atomic_write_text  # noqa: E402

from .sweep import Point, weather_suffix  # noqa: E402

POINT_COLS = ("scene", "lidar", "beams", "beam_mode", "max_range", "lidar_weather", "method", "boxes")
CSV_COLS = POINT_COLS + ("class", "metric", "iou", "difficulty", "range_m", "n_gt", "ap_r40", "ap_r11",
                        "ap_r40_measured")
ERR_COLS = POINT_COLS + ("class", "match", "range_m", "n", "centre_mean", "centre_median",
                         "depth_mean", "depth_median", "h_mean", "w_mean", "l_mean", "yaw_deg_mean",
                         "yaw_mod_pi_deg_mean")


def point_fields(pt: Point) -> dict:
    s = pt.scan
    return {"scene": pt.scene, "lidar": s.lidar if s else "-", "beams": s.beams if s else "-",
            "beam_mode": s.mode if s else "-",
            "max_range": "-" if s is None or s.max_range is None else f"{s.max_range:g}",
            "lidar_weather": "-" if s is None or s.weather is None else weather_suffix(s.weather)[1:],
            "method": pt.method, "boxes": pt.boxes}


def _num(v) -> str:
    return "" if v is None else f"{v:.4f}"


def _range_label(lo: float, hi: float | None) -> str:
    """'20-40', or '80+' for the open-ended last bin (its edge is null in the JSON)."""
    return f"{lo:g}+" if hi is None or not math.isfinite(hi) else f"{lo:g}-{hi:g}"


def metric_rows(results: list[tuple[Point, dict]]) -> list[dict]:
    """Every AP of every point: overall (strict and loose thresholds) and per distance bin, the
    devkit's AP|R40 and R11 and AP|R40 on the measured recall (`kitti.eval.ap`)."""
    rows = []
    none = [None] * 3
    for pt, ev in results:
        base = point_fields(pt)
        measured = ev.get("ap_r40_measured_recall", {})
        for iou, table in (("strict", ev["ap"]), ("loose", ev.get("ap_loose", {}))):
            for cls, per_metric in table.items():
                for metric, ap in per_metric.items():
                    m = measured.get(cls, {}).get(iou, {}).get(metric, none)
                    for i, d in enumerate(DIFFS):
                        rows.append({**base, "class": cls, "metric": metric, "iou": iou,
                                     "difficulty": d, "range_m": "all",
                                     "n_gt": ev.get("n_gt", {}).get(cls, [""] * 3)[i],
                                     "ap_r40": _num(ap["R40"][i]), "ap_r11": _num(ap["R11"][i]),
                                     "ap_r40_measured": _num(m[i])})
        for b in (ev.get("range_bins") or {}).get("bins", []):
            label = _range_label(*b["range"])
            for cls, per_metric in b["ap"].items():
                for metric, ap in per_metric.items():
                    m = b.get("ap_r40_measured", {}).get(cls, {}).get(metric, none)
                    for i, d in enumerate(DIFFS):
                        rows.append({**base, "class": cls, "metric": metric, "iou": "strict",
                                     "difficulty": d, "range_m": label, "n_gt": b["n_gt"][cls][i],
                                     "ap_r40": _num(ap["R40"][i]), "ap_r11": _num(ap["R11"][i]),
                                     "ap_r40_measured": _num(m[i])})
    return rows


def error_rows(results: list[tuple[Point, dict]]) -> list[dict]:
    rows = []
    for pt, ev in results:
        base = point_fields(pt)
        for how, per_class in ev.get("errors", {}).items():
            for cls, d in per_class.items():
                parts = [("all", d["all"])] + [(_range_label(*b["range"]), b) for b in d.get("bins", [])]
                for label, s in parts:
                    rows.append({**base, "class": cls, "match": how, "range_m": label, "n": s["n"],
                                 "centre_mean": _num(s["centre"]["mean"]),
                                 "centre_median": _num(s["centre"]["median"]),
                                 "depth_mean": _num(s["depth"]["mean"]),
                                 "depth_median": _num(s["depth"]["median"]),
                                 "h_mean": _num(s["h"]["mean"]), "w_mean": _num(s["w"]["mean"]),
                                 "l_mean": _num(s["l"]["mean"]),
                                 "yaw_deg_mean": _num(s["yaw_deg"]["mean"]),
                                 "yaw_mod_pi_deg_mean": _num(s["yaw_mod_pi_deg"]["mean"])})
    return rows


def write_csv(path: Path, rows: list[dict], cols: tuple[str, ...]) -> None:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    atomic_write_text(path, buf.getvalue())


def _config_label(row: dict) -> str:
    if row["beams"] == "-":
        return "no LiDAR"
    mode = "" if row["beam_mode"] == "native" else " (rings dropped)"
    rng = "" if row["max_range"] == "-" else f", {row['max_range']} m"
    weather = "" if row.get("lidar_weather", "-") == "-" else f", {row['lidar_weather']}"
    return f"{row['lidar']} {row['beams']} beams{mode}{rng}{weather}"


def summary_table(rows: list[dict], cls: str, metric: str, iou: str = "strict") -> str:
    """Markdown: one line per method x boxes x scan, AP|R40 easy / moderate / hard."""
    sel = [r for r in rows if r["class"] == cls and r["metric"] == metric and r["iou"] == iou
           and r["range_m"] == "all"]
    by, n_gt = defaultdict(dict), defaultdict(dict)
    for r in sel:
        key = (r["boxes"], r["method"], _config_label(r))
        by[key][r["difficulty"]] = r["ap_r40"]
        n_gt[key][r["difficulty"]] = r["n_gt"]
    out = ["| boxes | method | LiDAR | easy | moderate | hard | truth boxes (e / m / h) |",
           "|---|---|---|---:|---:|---:|---:|"]
    for key, v in by.items():
        boxes, method, cfg = key
        out.append(f"| {boxes} | {method} | {cfg} | " + " | ".join(
            f"{float(v[d]):.2f}" if v.get(d) else "-" for d in DIFFS) + " | "
            + " / ".join(str(n_gt[key].get(d, "")) for d in DIFFS) + " |")
    return "\n".join(out)


def range_table(rows: list[dict], cls: str, metric: str, boxes: str) -> str:
    """Markdown: AP|R40 (moderate) on the measured recall per distance bin, one line per method x
    scan, and the bins' truth counts: a bin of a few dozen cars would read mostly its count in the
    devkit's AP|R40 (capped at (n - 1) / 40 up to 40 truth boxes)."""
    sel = [r for r in rows if r["class"] == cls and r["metric"] == metric and r["iou"] == "strict"
           and r["difficulty"] == "moderate" and r["range_m"] != "all" and r["boxes"] == boxes]
    bins = list(dict.fromkeys(r["range_m"] for r in sel))
    by, n_gt = defaultdict(dict), {}
    for r in sel:
        by[(r["method"], _config_label(r))][r["range_m"]] = (r["ap_r40_measured"], r["n_gt"])
        n_gt[r["range_m"]] = r["n_gt"]
    out = ["| method | LiDAR | " + " | ".join(f"{b} m" for b in bins) + " |",
           "|---|---|" + "---:|" * len(bins),
           "| | truth boxes | " + " | ".join(str(n_gt[b]) for b in bins) + " |"]
    for (method, cfg), v in by.items():
        cells = []
        for b in bins:
            ap, n = v.get(b, ("", 0))
            cells.append(f"{float(ap):.1f}" if ap and int(n) > 0 else "-")
        out.append(f"| {method} | {cfg} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def _plot_by_range(sel: list[dict], value: str, ylabel: str, path: Path, ylim=None,
                   counts: dict[float, str] | None = None) -> None:
    """One panel per method x boxes, one line per LiDAR configuration, `value` against distance;
    `counts` (bin start: truth boxes) labels each bin with how many cars its point rests on."""
    panels = list(dict.fromkeys((r["method"], r["boxes"]) for r in sel))
    if not panels:
        return
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4), squeeze=False,
                             sharey=True)
    for ax, (method, boxes) in zip(axes[0], panels):
        lines = defaultdict(list)
        for r in sel:
            if (r["method"], r["boxes"]) == (method, boxes):
                lo = float(r["range_m"].split("-")[0].rstrip("+"))
                lines[_config_label(r)].append((lo, float(r[value])))
        for label, pts in lines.items():
            pts.sort()
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", ms=3, label=label)
        ax.set_title(f"{method}, {boxes} boxes", fontsize=9)
        ax.set_xlabel("distance bin start (m)" + ("\n(truth boxes in the bin)" if counts else ""))
        if counts:
            ax.set_xticks(sorted(counts), [f"{lo:g}\n({counts[lo]})" for lo in sorted(counts)], fontsize=7)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    axes[0][0].set_ylabel(ylabel)
    if ylim:
        axes[0][0].set_ylim(*ylim)
    _save(fig, path)


def plot_ap_vs_range(rows: list[dict], cls: str, metric: str, path: Path) -> None:
    """AP|R40 moderate on the measured recall against distance (`range_table` says why)."""
    sel = [r for r in rows if r["class"] == cls and r["metric"] == metric and r["iou"] == "strict"
           and r["difficulty"] == "moderate" and r["range_m"] != "all" and r["ap_r40_measured"]
           and int(r["n_gt"]) > 0]
    counts = {float(r["range_m"].split("-")[0].rstrip("+")): r["n_gt"] for r in sel}
    _plot_by_range(sel, "ap_r40_measured", f"{cls} {metric.upper()} AP|R40 moderate,\nmeasured recall",
                   path, (0, 102), counts)


def plot_errors_vs_range(err: list[dict], cls: str, path: Path, match: str = "centre") -> None:
    sel = [r for r in err if r["class"] == cls and r["range_m"] != "all" and r["match"] == match
           and r["centre_median"]]
    _plot_by_range(sel, "centre_median", f"{cls} median centre error (m), {match} match", path)


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def write_report(results: list[tuple[Point, dict]], out: Path, title: str, intro: str = "",
                 cls: str = "Car") -> list[dict]:
    """metrics.csv, errors.csv, plots and report.md under `out`; returns the metric rows."""
    out.mkdir(parents=True, exist_ok=True)
    rows, err = metric_rows(results), error_rows(results)
    write_csv(out / "metrics.csv", rows, CSV_COLS)
    write_csv(out / "errors.csv", err, ERR_COLS)
    plot_ap_vs_range(rows, cls, "3d", out / "ap_vs_distance_3d.png")
    plot_ap_vs_range(rows, cls, "bev", out / "ap_vs_distance_bev.png")
    plot_errors_vs_range(err, cls, out / "errors_vs_distance.png")
    md = [f"# {title}", "", intro, "",
          "AP is the official KITTI AP|R40 (`kitti.eval`). With 40 or fewer truth boxes in a "
          "difficulty, even a perfect method scores at most (n - 1)/40 there, as in the official "
          "code: the truth counts are listed next to every table. The tables and plots by distance, "
          "whose bins hold few cars, give AP|R40 on the measured recall instead (each threshold "
          "read at its own recall, as AP|R40 is defined; `kitti.eval.ap`); `metrics.csv` holds "
          "both (`ap_r40`, `ap_r40_measured`).", "",
          f"## {cls} 3D AP|R40 (IoU 0.7), by method, boxes and LiDAR", "", summary_table(rows, cls, "3d"),
          "", f"## {cls} BEV AP|R40 (IoU 0.7)", "", summary_table(rows, cls, "bev"),
          "", f"## {cls} 3D AP|R40 at the loose threshold (IoU 0.5)", "",
          summary_table(rows, cls, "3d", "loose")]
    for boxes in dict.fromkeys(r["boxes"] for r in rows):
        md += ["", f"## {cls} 3D AP|R40 moderate by distance, on the measured recall ({boxes} boxes)", "",
               range_table(rows, cls, "3d", boxes)]
    md += ["", "![AP versus distance](ap_vs_distance_3d.png)", "",
           "![BEV AP versus distance](ap_vs_distance_bev.png)", "",
           "![Errors versus distance](errors_vs_distance.png)", "",
           f"## {cls} error statistics (centre-matched pairs, all distances)", "",
           _error_table(err, cls)]
    atomic_write_text(out / "report.md", "\n".join(md) + "\n")
    return rows


def _error_table(err: list[dict], cls: str) -> str:
    out = ["| boxes | method | LiDAR | n | centre mean (m) | centre median (m) | depth median (m) | "
           "h / w / l mean (m) | yaw mean (deg) | yaw mod pi (deg) |",
           "|---|---|---|---:|---:|---:|---:|---|---:|---:|"]
    for r in err:
        if r["class"] != cls or r["range_m"] != "all" or r["match"] != "centre":
            continue
        out.append(f"| {r['boxes']} | {r['method']} | {_config_label(r)} | {r['n']} | "
                   f"{_f(r['centre_mean'])} | {_f(r['centre_median'])} | {_f(r['depth_median'])} | "
                   f"{_f(r['h_mean'])} / {_f(r['w_mean'])} / {_f(r['l_mean'])} | "
                   f"{_f(r['yaw_deg_mean'], 1)} | {_f(r['yaw_mod_pi_deg_mean'], 1)} |")
    return "\n".join(out)


def _f(v: str, digits: int = 2) -> str:
    return f"{float(v):.{digits}f}" if v else "-"
