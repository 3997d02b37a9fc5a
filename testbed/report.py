"""Sweep and run reports: one long CSV of every number, a Markdown summary and plots.

Input is the evaluation JSON of each point (`kitti.eval`, as `testbed evaluate --json` writes it) (keys `ap`, `range_bins`, `errors`)
and, where given, how sure each number is (`testbed.uncertainty`: AP intervals and paired changes,
from the points' files); nothing is recomputed here, so a report can be rebuilt from a finished
sweep at any time.
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
from matplotlib.ticker import MaxNLocator  # noqa: E402

from kitti.eval.protocol import DIFFICULTIES as DIFFS  # noqa: E402
from kitti.io import atomic_path, atomic_write_text  # noqa: E402

from .sweep import Point, ScanConfig, weather_suffix  # noqa: E402
from .uncertainty import AXES, PairedChange, Uncertainty, ap_values, range_label  # noqa: E402

POINT_COLS = ("scene", "lidar", "beams", "beam_mode", "max_range", "lidar_weather", "method", "boxes")
CSV_COLS = POINT_COLS + ("class", "metric", "iou", "difficulty", "range_m", "n_gt", "ap_r40", "ap_r11",
                        "ap_r40_measured", "ap_r40_lo", "ap_r40_hi", "ap_r11_lo", "ap_r11_hi",
                        "ap_r40_measured_lo", "ap_r40_measured_hi")
AP_COLS = ("ap_r40", "ap_r11", "ap_r40_measured")  # each with its interval: <col>_lo, <col>_hi
ERR_COLS = POINT_COLS + ("class", "match", "range_m", "n", "centre_mean", "centre_median",
                         "depth_mean", "depth_median", "h_mean", "w_mean", "l_mean", "yaw_deg_mean",
                         "yaw_mod_pi_deg_mean")
PAIRED_COLS = POINT_COLS + ("axis", "reference", "class", "measure", "range_m", "n", "value",
                            "reference_value", "change", "change_lo", "change_hi", "decided")


def point_fields(pt: Point) -> dict:
    s = pt.scan
    return {"scene": pt.scene, "lidar": s.lidar if s else "-", "beams": s.beams if s else "-",
            "beam_mode": s.mode if s else "-",
            "max_range": "-" if s is None or s.max_range is None else f"{s.max_range:g}",
            "lidar_weather": "-" if s is None or s.weather is None else weather_suffix(s.weather)[1:],
            "method": pt.method, "boxes": pt.boxes}


def _num(v) -> str:
    return "" if v is None else f"{v:.4f}"


def metric_rows(results: list[tuple[Point, dict]], u: Uncertainty | None = None) -> list[dict]:
    """Every AP of every point: overall (strict and loose thresholds) and per distance bin, the
    devkit's AP|R40 and R11 and AP|R40 on the measured recall (`kitti.eval.ap`), each with its
    95 % interval where `u` has the point's draws (blank where it has none)."""
    rows = []
    for pt, ev in results:
        base = point_fields(pt)
        intervals = u.points[pt].intervals if u is not None else {}
        for key, (*aps, n_gt) in ap_values(ev).items():
            iou, cls, metric, difficulty, range_m = key
            row = {**base, "class": cls, "metric": metric, "iou": iou, "difficulty": difficulty,
                   "range_m": range_m, "n_gt": n_gt}
            for col, v, iv in zip(AP_COLS, aps, intervals.get(key, (None,) * 3)):
                lo, hi = iv or (None, None)
                row |= {col: _num(v), f"{col}_lo": _num(lo), f"{col}_hi": _num(hi)}
            rows.append(row)
    return rows


def paired_rows(changes: list[PairedChange]) -> list[dict]:
    """paired.csv: each paired change with the compared point's fields and the reference named by
    its key (scan, method and boxes)."""
    return [{**point_fields(c.point), "axis": c.axis, "reference": c.reference.key.split("/", 1)[1],
             "class": c.cls, "measure": c.measure, "range_m": c.range_m, "n": c.change.n,
             "value": _num(c.value), "reference_value": _num(c.reference_value),
             "change": _num(c.change.mean), "change_lo": _num(c.change.lo),
             "change_hi": _num(c.change.hi), "decided": "yes" if c.change.decided else "no"}
            for c in changes]


def error_rows(results: list[tuple[Point, dict]]) -> list[dict]:
    rows = []
    for pt, ev in results:
        base = point_fields(pt)
        for how, per_class in ev.get("errors", {}).items():
            for cls, d in per_class.items():
                parts = [("all", d["all"])] + [(range_label(*b["range"]), b) for b in d.get("bins", [])]
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
    """The scan as its folder names it (`ScanConfig.sensor`): a native count the preset lacks is
    a `uniform` fan; rings dropped keep the preset's name."""
    if row["beams"] == "-":
        return "no LiDAR"
    sensor = ScanConfig(row["lidar"], int(row["beams"]), row["beam_mode"], None).sensor
    mode = "" if row["beam_mode"] == "native" else " (rings dropped)"
    rng = "" if row["max_range"] == "-" else f", {row['max_range']} m"
    weather = "" if row.get("lidar_weather", "-") == "-" else f", {row['lidar_weather']}"
    return f"{sensor} {row['beams']} beams{mode}{rng}{weather}"


def _ap_cell(r: dict | None) -> str:
    """AP|R40 and, where the row has one, its 95 % interval."""
    if r is None or not r["ap_r40"]:
        return "-"
    ci = f" [{float(r['ap_r40_lo']):.1f}, {float(r['ap_r40_hi']):.1f}]" if r["ap_r40_lo"] else ""
    return f"{float(r['ap_r40']):.2f}{ci}"


def summary_table(rows: list[dict], cls: str, metric: str, iou: str = "strict") -> str:
    """Markdown: one line per method x boxes x scan, AP|R40 easy / moderate / hard, each with its
    95 % interval where the rows have one."""
    sel = [r for r in rows if r["class"] == cls and r["metric"] == metric and r["iou"] == iou
           and r["range_m"] == "all"]
    by = defaultdict(dict)
    for r in sel:
        by[(r["boxes"], r["method"], _config_label(r))][r["difficulty"]] = r
    out = ["| boxes | method | LiDAR | easy | moderate | hard | truth boxes (e / m / h) |",
           "|---|---|---|---:|---:|---:|---:|"]
    for (boxes, method, cfg), v in by.items():
        out.append(f"| {boxes} | {method} | {cfg} | " + " | ".join(_ap_cell(v.get(d)) for d in DIFFS)
                   + " | " + " / ".join(str(v[d]["n_gt"]) if d in v else "" for d in DIFFS) + " |")
    return "\n".join(out)


def _scan_label(pt: Point) -> str:
    return _config_label(point_fields(pt))


def _point_label(pt: Point) -> str:
    return f"{pt.method}, {pt.boxes} boxes, {_scan_label(pt)}"


def _against(c: PairedChange, scan_label=_scan_label) -> str:
    """What the reference differs in: its boxes, method (and scan, where that differs too) or scan."""
    ref = c.reference
    if c.axis == "boxes":
        return f"{ref.boxes} boxes"
    if c.axis == "method":
        return ref.method + ("" if ref.scan == c.point.scan else f" ({scan_label(ref)})")
    return scan_label(ref)


def _change_cell(c: PairedChange, digits: int) -> str:
    ch = c.change
    return (f"{ch.mean:+.{digits}f} [{ch.lo:+.{digits}f}, {ch.hi:+.{digits}f}]"
            + (" *" if ch.decided else ""))


def paired_table(changes: list[PairedChange], cls: str, axis: str) -> str:
    """Markdown: one line per comparison along `axis` of `cls` over all distances: the point, its
    reference, the cars paired, mean 3D IoU at both, and each measure's change with its interval
    (`*`: the interval leaves out zero)."""
    sel = [c for c in changes if c.cls == cls and c.axis == axis and c.range_m == "all"]
    names = list(dict.fromkeys(c.measure for c in sel))
    by = defaultdict(dict)
    for c in sel:
        by[c.point, c.reference][c.measure] = c
    heads = ["change of " + ("mean 3D IoU" if m == "mean_iou_3d" else "the " + m.replace("_", " "))
             for m in names]
    out = [f"| point | against | {cls}s | mean 3D IoU (point / against) | " + " | ".join(heads) + " |",
           "|---|---|---:|---:|" + "---:|" * len(names)]
    for cs in by.values():
        iou = cs["mean_iou_3d"]
        out.append(f"| {_point_label(iou.point)} | {_against(iou)} | {iou.change.n} | "
                   f"{iou.value:.3f} / {iou.reference_value:.3f} | "
                   + " | ".join(_change_cell(cs[m], 3 if m == "mean_iou_3d" else 2) for m in names) + " |")
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


def _panels(n: int, width: float, height: float, cols: int = 3, **kw):
    """A figure of n panels, at most `cols` a row (wrapped to rows, so it stays readable at its
    size); the unused cells hidden. Returns the figure and the n axes."""
    ncols = min(cols, n)
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False, **kw)
    flat = list(axes.flat)
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def _float(v: str) -> float:
    return float(v) if v else math.nan


def _plot_by_range(sel: list[dict], value: str, ylabel: str, path: Path, ylim=None,
                   counts: dict[float, str] | None = None, band: bool = False) -> None:
    """One panel per method x boxes, one line per LiDAR configuration, `value` against distance,
    with its 95 % interval as a band where `band` (columns `<value>_lo`, `<value>_hi`); `counts`
    (bin start: truth boxes) labels each bin with how many cars its point rests on."""
    panels = list(dict.fromkeys((r["method"], r["boxes"]) for r in sel))
    if not panels:
        return
    fig, axes = _panels(len(panels), 4.6, 3.6, sharey=True)
    for ax, (method, boxes) in zip(axes, panels):
        lines = defaultdict(list)
        for r in sel:
            if (r["method"], r["boxes"]) == (method, boxes):
                lo = float(r["range_m"].split("-")[0].rstrip("+"))
                ci = (_float(r[f"{value}_lo"]), _float(r[f"{value}_hi"])) if band else ()
                lines[_config_label(r)].append((lo, float(r[value]), *ci))
        for label, pts in lines.items():
            x, y, *ci = zip(*sorted(pts))
            line, = ax.plot(x, y, marker="o", ms=3, label=label)
            if ci:
                ax.fill_between(x, ci[0], ci[1], color=line.get_color(), alpha=0.12, lw=0)
        ax.set_title(f"{method}, {boxes} boxes", fontsize=9)
        ax.set_xlabel("distance bin start (m)" + ("\n(truth boxes in the bin)" if counts else ""))
        if counts:
            ax.set_xticks(sorted(counts), [f"{lo:g}\n({counts[lo]})" for lo in sorted(counts)], fontsize=7)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel(ylabel)
    if ylim:
        axes[0].set_ylim(*ylim)
    _save(fig, path)


def plot_ap_vs_range(rows: list[dict], cls: str, metric: str, path: Path) -> None:
    """AP|R40 moderate on the measured recall against distance (`range_table` says why)."""
    sel = [r for r in rows if r["class"] == cls and r["metric"] == metric and r["iou"] == "strict"
           and r["difficulty"] == "moderate" and r["range_m"] != "all" and r["ap_r40_measured"]
           and int(r["n_gt"]) > 0]
    counts = {float(r["range_m"].split("-")[0].rstrip("+")): r["n_gt"] for r in sel}
    _plot_by_range(sel, "ap_r40_measured", f"{cls} {metric.upper()} AP|R40 moderate,\nmeasured recall"
                   + (" (band: 95 %)" if any(r["ap_r40_measured_lo"] for r in sel) else ""),
                   path, (0, 102), counts, band=True)


def plot_ap_vs_axis(rows: list[dict], cls: str, path: Path) -> None:
    """3D AP|R40 moderate (IoU 0.7, all distances) of every LiDAR configuration, one panel per
    method x boxes, with its 95 % interval as error bars where the rows have one."""
    sel = [r for r in rows if r["class"] == cls and r["metric"] == "3d" and r["iou"] == "strict"
           and r["difficulty"] == "moderate" and r["range_m"] == "all" and r["ap_r40"]]
    panels = list(dict.fromkeys((r["method"], r["boxes"]) for r in sel))
    if not panels:
        return
    fig, axes = _panels(len(panels), 4.6, 4.0, sharey=True)
    for ax, (method, boxes) in zip(axes, panels):
        pts = [r for r in sel if (r["method"], r["boxes"]) == (method, boxes)]
        y = [float(r["ap_r40"]) for r in pts]
        err = [[v - _float(r["ap_r40_lo"]) for v, r in zip(y, pts)],
               [_float(r["ap_r40_hi"]) - v for v, r in zip(y, pts)]]
        ax.errorbar(range(len(pts)), y, yerr=err, fmt="o", ms=4, capsize=3)
        ax.set_xticks(range(len(pts)), [_config_label(r) for r in pts], rotation=35, ha="right",
                      fontsize=7)
        ax.set_title(f"{method}, {boxes} boxes", fontsize=9)
        ax.grid(alpha=0.3)
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel(f"{cls} 3D AP|R40 moderate\n(bars: 95 % interval)")
    axes[0].set_ylim(0, 102)
    _save(fig, path)


def _short_scan(pt: Point) -> str:
    s = pt.scan
    if s is None:
        return "no LiDAR"
    rng = "" if s.max_range is None else f" {s.max_range:g}m"
    return f"{s.beams}b{' dropped' if s.mode == 'dropped' else ''}{rng}{weather_suffix(s.weather)}"


def _bar_label(c: PairedChange) -> str:
    return f"{c.point.method}/{c.point.boxes} {_short_scan(c.point)} vs {_against(c, _short_scan)}"


def plot_paired(changes: list[PairedChange], cls: str, path: Path) -> None:
    """The paired change of mean 3D IoU (all distances) of every comparison, one panel per axis,
    as bars with their 95 % interval; blue where the interval leaves out zero."""
    sel = [c for c in changes if c.cls == cls and c.measure == "mean_iou_3d" and c.range_m == "all"]
    axes_used = [a for a in AXES if any(c.axis == a for c in sel)]
    if not axes_used:
        return
    tallest = max(sum(c.axis == a for c in sel) for a in axes_used)
    fig, axes = _panels(len(axes_used), 5.4, 1.6 + 0.24 * tallest, cols=2)
    for ax, axis in zip(axes, axes_used):
        cs = [c for c in sel if c.axis == axis]
        y = [tallest - 1 - k for k in range(len(cs))]  # the plan's order from the top
        mean, lo, hi = ([getattr(c.change, a) for c in cs] for a in ("mean", "lo", "hi"))
        ax.barh(y, mean, xerr=[[m - v for m, v in zip(mean, lo)], [v - m for m, v in zip(mean, hi)]],
                color=["tab:blue" if c.change.decided else "lightgray" for c in cs], capsize=2,
                error_kw={"lw": 0.8})
        ax.set_yticks(y, [_bar_label(c) for c in cs], fontsize=6.5)
        ax.set_ylim(-0.7, tallest - 0.3)
        left, right = min(0.0, *lo), max(0.0, *hi)
        pad = 0.08 * (right - left) or 0.01
        ax.set_xlim(left - pad, right + pad)  # zero always in view, with room on both sides
        ax.axvline(0, color="black", lw=0.6)
        ax.xaxis.set_major_locator(MaxNLocator(5))
        ax.tick_params(axis="x", labelsize=7)
        ax.set_title(f"{axis}: change of {cls} mean 3D IoU\n(blue: 95 % interval leaves out 0)", fontsize=8)
        ax.grid(axis="x", alpha=0.3)
    _save(fig, path)


def plot_errors_vs_range(err: list[dict], cls: str, path: Path, match: str = "centre") -> None:
    sel = [r for r in err if r["class"] == cls and r["range_m"] != "all" and r["match"] == match
           and r["centre_median"]]
    _plot_by_range(sel, "centre_median", f"{cls} median centre error (m), {match} match", path)


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def _paired_section(u: Uncertainty | None, cls: str) -> list[str]:
    """The report's first section: which effects the sweep settles, and how the intervals are made."""
    if u is None:
        return ["No intervals: this report was written without bootstrap draws "
                "(`testbed.uncertainty.measure`), so its AP figures come without a 95 % interval "
                "and no comparison is paired.", ""]
    units = "; ".join(f"{scene}: {what}" for scene, what in u.units.items())
    md = [f"## What the sweep settles: paired changes against a reference point ({cls}, moderate, "
          "all distances)", "",
          f"Each line: a point against its reference, which differs from it along one axis; the "
          f"change of the same {cls}s' 3D IoU (and of their shares above the strict and the loose "
          f"threshold), mean [95 % interval over {u.draws} bootstrap draws of the frames]; `*` where "
          "the interval leaves out zero: the sweep settles that effect. Without `*` these frames "
          "cannot tell it from none.", ""]
    axes = [a for a in AXES if any(c.axis == a and c.cls == cls for c in u.changes)]
    if not axes:
        return md + [f"This sweep compares no two points with {cls}s (one value on every axis).", ""]
    for axis in axes:
        md += [f"### {axis}", "", paired_table(u.changes, cls, axis), ""]
    return md + [
        "![Paired changes](paired_changes.png)", "",
        f"Images and labels are the same at every point, so each moderate {cls} is scored at every "
        "point: the 3D IoU of the lifted box whose 2D box claims it (2D IoU 0.5 or more, best first; "
        "0 where none does). A reference has the compared axis at its first value in the spec and "
        "every other axis as the point has it; a dropped-ring scan is compared along `beams` with "
        "the 64-beam scan its rings come from where the first listed count is not dropped to, and "
        "an image-only method along `method` with the "
        f"first method on the first listed scan. The draws ({units}) are seeded and the same at "
        "every point and for every AP interval. Every class and distance bin: `paired.csv`; AP "
        "intervals: `metrics.csv` (`*_lo`, `*_hi`), the tables and plots below.", ""]


def write_report(results: list[tuple[Point, dict]], out: Path, title: str, intro: str = "",
                 cls: str = "Car", uncertainty: Uncertainty | None = None) -> list[dict]:
    """metrics.csv, errors.csv, plots and report.md under `out`, and with `uncertainty` (from
    `testbed.uncertainty.measure`) the AP intervals and paired.csv; returns the metric rows."""
    out.mkdir(parents=True, exist_ok=True)
    rows, err = metric_rows(results, uncertainty), error_rows(results)
    write_csv(out / "metrics.csv", rows, CSV_COLS)
    write_csv(out / "errors.csv", err, ERR_COLS)
    if uncertainty is not None:
        write_csv(out / "paired.csv", paired_rows(uncertainty.changes), PAIRED_COLS)
        plot_paired(uncertainty.changes, cls, out / "paired_changes.png")
    plot_ap_vs_axis(rows, cls, out / "ap_vs_axis.png")
    plot_ap_vs_range(rows, cls, "3d", out / "ap_vs_distance_3d.png")
    plot_ap_vs_range(rows, cls, "bev", out / "ap_vs_distance_bev.png")
    plot_errors_vs_range(err, cls, out / "errors_vs_distance.png")
    md = [f"# {title}", "", intro, "", *_paired_section(uncertainty, cls),
          "AP is the official KITTI AP|R40 (`kitti.eval`). With 40 or fewer truth boxes in a "
          "difficulty, even a perfect method scores at most (n - 1)/40 there, as in the official "
          "code: the truth counts are listed next to every table. The tables and plots by distance, "
          "whose bins hold few cars, give AP|R40 on the measured recall instead (each threshold "
          "read at its own recall, as AP|R40 is defined; `kitti.eval.ap`); `metrics.csv` holds "
          "both (`ap_r40`, `ap_r40_measured`)" + (
              ", each with its 95 % interval over the draws above (`[lo, hi]` in the tables, bars "
              "and bands in the plots)." if uncertainty else "."), "",
          f"## {cls} 3D AP|R40 (IoU 0.7), by method, boxes and LiDAR", "", summary_table(rows, cls, "3d"),
          "", "![3D AP by LiDAR configuration](ap_vs_axis.png)",
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
