"""Euro NCAP-style scoring of the `ncap_*` scenarios: avoidance and impact speed per car speed.

Euro NCAP's AEB pedestrian tests (CPNA, CPFA, CPNC) sweep the car's speed and score, per test speed,
whether the car avoided the dummy and, if not, how fast it hit it. The `ncap_*` scenarios draw the ego's
speed per seed from 20-60 km/h, so here episodes are binned by the ego's speed after reset (10 km/h bins)
and each bin counts the episodes' outcomes (`EpisodeResult.ncap_outcome`: avoided, outrun, impact, not
tested), the avoidance rate over the tested episodes and the mean impact speed of the impacts (the ego's
speed when the contact began, as Euro NCAP measures it; the key pedestrian is a dummy that reacts to
nothing, `ConflictConfig.dummy`). Written into ``report.md``.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from crossing_env.safety import DEFAULT_METRICS
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


OUTCOMES = ("avoided", "outrun", "impact", "not tested")
"""An NCAP episode's outcome (`EpisodeResult.ncap_outcome`), in the table's order."""


@dataclass(frozen=True)
class NcapRow:
    """One (scenario, policy, car-speed bin) of the NCAP table."""

    scenario: str
    policy: str
    band: str
    """Car-speed bin, "lo-hi" km/h."""
    counts: dict[str, int]
    """Episodes per outcome (`OUTCOMES`)."""
    impact_kmh: float
    """Mean impact speed (the car's speed at contact) of the impact episodes, km/h; nan if none."""

    @property
    def episodes(self) -> int:
        """Episodes in the bin."""
        return sum(self.counts.values())

    @property
    def tested(self) -> int:
        """Episodes in which the dummy was released: the test ran."""
        return self.episodes - self.counts["not tested"]

    @property
    def avoidance(self) -> float:
        """Avoided / tested (outrunning is not avoiding; untested episodes count for nothing); nan if none."""
        return self.counts["avoided"] / self.tested if self.tested else math.nan


def _outcome(result: dict) -> str:
    """The episode's outcome; records written before outcomes existed: impact or avoided from the contacts."""
    outcome = result.get("ncap_outcome") or ""
    if outcome:
        return outcome
    return "impact" if result.get("pedestrian_collisions", 0) > 0 else "avoided"


def ncap_rows(records: Sequence[EpisodeRecord]) -> list[NcapRow]:
    """One row per (scenario, policy, car-speed bin) of the `ncap_*` episodes, in that order."""
    groups: dict[tuple[str, str, tuple[int, int]], list[EpisodeRecord]] = defaultdict(list)
    for rec in records:
        name = Path(rec.task.scenario).stem
        speed_bin = _bin(rec.initial_speed)
        if name.startswith(PREFIX) and speed_bin is not None:
            groups[(name, rec.task.policy, speed_bin)].append(rec)
    rows = []
    for (name, policy, (lo, hi)), recs in sorted(groups.items()):
        counts = dict.fromkeys(OUTCOMES, 0)
        speeds = []
        for r in recs:
            outcome = _outcome(r.result)
            counts[outcome] += 1
            if outcome == "impact" and r.result.get("max_impact_speed") is not None:
                speeds.append(r.result["max_impact_speed"])
        impact = 3.6 * sum(speeds) / len(speeds) if speeds else float("nan")
        rows.append(NcapRow(name, policy, f"{lo}-{hi}", counts, impact))
    return rows


def ncap_markdown(records: Sequence[EpisodeRecord]) -> str:
    """The report section (empty when the run has no `ncap_*` scenario)."""
    rows = ncap_rows(records)
    if not rows:
        return ""
    lines = [
        "## NCAP-style scoring (ncap_* scenarios)",
        "",
        "Episodes binned by the car's speed after reset. Each episode is avoided (no contact with the"
        " dummy), outrun (no contact, but the car's rear cleared the dummy's path less than"
        f" {DEFAULT_METRICS.outrun_margin:g} s before the dummy reached the car's side: it got away by"
        " speed),"
        " impact, or not tested (the dummy was never released: the car never came near). Avoided = avoided /"
        " tested episodes (outrun is not avoided; '-' = none tested); impact speed = mean of the car's speed"
        " at contact over the impact episodes ('-' = none).",
        "",
        "| scenario | policy | car speed km/h | episodes | avoided | outrun | impact | not tested | avoided"
        " (of tested) | impact speed km/h |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        c = row.counts
        rate = "-" if math.isnan(row.avoidance) else f"{row.avoidance:.2f}"
        shown = "-" if math.isnan(row.impact_kmh) else f"{row.impact_kmh:.1f}"
        lines.append(
            f"| {row.scenario} | {row.policy} | {row.band} | {row.episodes} | {c['avoided']} | {c['outrun']}"
            f" | {c['impact']} | {c['not tested']} | {rate} | {shown} |"
        )
    return "\n".join(lines) + "\n"
