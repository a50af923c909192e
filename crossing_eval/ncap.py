"""Euro NCAP-style scoring of the `ncap_*` scenarios: avoidance and impact speed per car speed.

Euro NCAP's AEB pedestrian tests (CPNA, CPFA, CPNC) sweep the car's speed and score, per test speed,
whether the car avoided the dummy and, if not, how fast it hit it. The `ncap_*` scenarios draw the ego's
speed per seed from 20-60 km/h, so here episodes are binned by the ego's speed after reset (10 km/h bins)
and each bin reports the share of episodes without a pedestrian contact and the mean impact speed of
those with one (the ego's speed when the contact began, as Euro NCAP measures it; the key pedestrian is a
dummy that reacts to nothing, `ConflictConfig.dummy`). Written into ``report.md``.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

from crossing_eval.tasks import EpisodeRecord

PREFIX = "ncap_"
"""Scenarios scored this way: the built-in NCAP family and any scenario file named like it."""
BIN_KMH = 10.0
"""Width of a car-speed bin (km/h)."""


def _bin(speed_ms: float) -> tuple[int, int] | None:
    if not math.isfinite(speed_ms):
        return None
    low = int(math.floor(speed_ms * 3.6 / BIN_KMH) * BIN_KMH)
    return low, int(low + BIN_KMH)


def ncap_rows(records: Sequence[EpisodeRecord]) -> list[tuple[str, str, str, int, float, float]]:
    """(scenario, policy, "lo-hi km/h", episodes, avoidance rate, mean impact speed km/h or nan) rows."""
    groups: dict[tuple[str, str, tuple[int, int]], list[EpisodeRecord]] = defaultdict(list)
    for rec in records:
        name = Path(rec.task.scenario).stem
        speed_bin = _bin(rec.initial_speed)
        if name.startswith(PREFIX) and speed_bin is not None:
            groups[(name, rec.task.policy, speed_bin)].append(rec)
    rows = []
    for (name, policy, (lo, hi)), recs in sorted(groups.items()):
        hits = [r for r in recs if r.result.get("pedestrian_collisions", 0) > 0]
        speeds = [r.result["max_impact_speed"] for r in hits if r.result.get("max_impact_speed") is not None]
        impact = 3.6 * sum(speeds) / len(speeds) if speeds else float("nan")
        rows.append((name, policy, f"{lo}-{hi}", len(recs), 1.0 - len(hits) / len(recs), impact))
    return rows


def ncap_markdown(records: Sequence[EpisodeRecord]) -> str:
    """The report section (empty when the run has no `ncap_*` scenario)."""
    rows = ncap_rows(records)
    if not rows:
        return ""
    lines = [
        "## NCAP-style scoring (ncap_* scenarios)",
        "",
        "Episodes binned by the car's speed after reset; avoided = no contact with a pedestrian; impact speed"
        " = mean of the car's speed at contact over the episodes with one ('-' = none).",
        "",
        "| scenario | policy | car speed km/h | episodes | avoided | impact speed km/h |",
        "|---|---|---|---|---|---|",
    ]
    for name, policy, band, n, avoided, impact in rows:
        shown = "-" if math.isnan(impact) else f"{impact:.1f}"
        lines.append(f"| {name} | {policy} | {band} | {n} | {avoided:.2f} | {shown} |")
    return "\n".join(lines) + "\n"
