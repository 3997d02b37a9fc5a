"""Every AP of an evaluation on each bootstrap draw of its frames, overall and per distance bin.

`bootstrap.bootstrap_ap` draws the overall AP of a few result sets; a sweep's report lists AP per
distance bin too, and each number there needs its own interval. Here each draw's AP comes in the
shape of `evaluate`'s JSON (keys `ap`, `ap_loose`, `n_gt`, `ap_r40_measured_recall`,
`range_bins`), so whatever reads an evaluation reads a draw the same way and finds every number's
draws under the same keys. As in `bootstrap_ap`, the overlaps are computed once and a draw takes
its frames' rows and overlaps (`Packed.take`); the error breakdowns, which no interval reads, are
left out.
"""

from __future__ import annotations

from typing import Iterable, Iterator, Mapping, Sequence

import numpy as np

from ..labels import Object3D
from .evaluate import _range_bins, check_request, class_ap, overlaps_needed
from .frames import pack
from .overlaps import dontcare_overlap, pair_overlaps
from .protocol import METRICS


def drawn_evaluations(gt: Mapping[str, Sequence[Object3D]], dt: Mapping[str, Sequence[Object3D]],
                      draws: Iterable[np.ndarray], classes: Sequence[str],
                      metrics: Sequence[str] = METRICS,
                      range_bins: Sequence[float] | None = None) -> Iterator[dict]:
    """For each draw (indices into sorted(gt), repeats allowed: `bootstrap.draw_frames`), the AP
    `evaluate(gt, dt, classes, metrics, range_bins)` gives on the drawn frames, as its JSON holds
    it (a frame drawn twice counts twice)."""
    classes, metrics = list(classes), list(metrics)
    check_request(classes, metrics)
    edges = None if range_bins is None else np.asarray(range_bins, dtype=float)
    p = pack(gt, dt)
    ovs = {m: pair_overlaps(p, m) for m in overlaps_needed(metrics)}
    dc_ov = dontcare_overlap(p.dt, p.dc)
    for picks in draws:
        q, slots, rows = p.take(picks)
        q_ovs, q_dc = {m: v[slots] for m, v in ovs.items()}, dc_ov[rows]
        ev: dict = {"ap": {}, "ap_loose": {}, "n_gt": {}, "ap_r40_measured_recall": {}}
        absent = {}
        for cls in classes:  # as `evaluate` files them
            strict, loose, ab = class_ap(q, cls, metrics, q_ovs, q_dc)
            keep = [m for m in strict.ap if m in metrics]
            absent[cls] = ab
            ev["ap"][cls] = {m: strict.ap[m] for m in keep}
            ev["ap_loose"][cls] = loose.ap
            ev["n_gt"][cls] = strict.n_gt
            ev["ap_r40_measured_recall"][cls] = {"strict": {m: strict.measured[m] for m in keep},
                                                 "loose": loose.measured}
        if edges is not None:
            ev["range_bins"] = _range_bins(q, classes, metrics, absent, q_ovs, q_dc, edges, False)
        yield ev
