"""Summaries of a run (per policy, per scenario and policy, overall) and the printed table."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from crossing_env.safety import EpisodeResult
from crossing_eval.statistics import aggregate, censored_delay
from crossing_eval.tasks import EpisodeRecord
from scenarios import load_scenario

TABLE_COLUMNS = (
    ("policy", "policy"),
    ("n", "episodes"),
    ("collision rate [95% CI]", None),
    ("minTTC p5/p50 s", None),
    ("PET p5 s", "pet_pedestrian_first_p5"),
    ("DRAC mean", "drac_crossing_mean"),
    ("hard brakes/ep", "hard_brakes_per_episode"),
    ("yield compl. (n)", None),
    ("pass rate", "pass_rate"),
    ("delay s (censored)", "censored_mean_delay"),
)
"""Table columns: (header, `aggregate` key, or None where the cell combines several keys)."""


def summarise(records: Sequence[EpisodeRecord]) -> dict[str, Any]:
    """Per policy, per (scenario, policy) and overall aggregates (`crossing_eval.statistics.aggregate`).

    Each aggregate also holds the censored delay (`crossing_eval.statistics.censored_delay`): episodes
    that never pass count at their scenario's duration.
    """
    horizons = {s: load_scenario(s).duration for s in {r.task.scenario for r in records}}
    results = [EpisodeResult.from_dict(r.result) for r in records]
    by_policy: dict[str, list[Any]] = {}
    by_pair: dict[str, list[Any]] = {}
    for rec, res in zip(records, results, strict=True):
        by_policy.setdefault(rec.task.policy, []).append((res, horizons[rec.task.scenario]))
        by_pair.setdefault(f"{rec.task.scenario}/{rec.task.policy}", []).append(
            (res, horizons[rec.task.scenario])
        )
    every = [(res, horizons[rec.task.scenario]) for rec, res in zip(records, results, strict=True)]
    return {
        "per_policy": {k: _aggregate(v) for k, v in by_policy.items()},
        "per_scenario_policy": {k: _aggregate(v) for k, v in sorted(by_pair.items())},
        "overall": _aggregate(every),
    }


def _aggregate(pairs: Sequence[tuple[EpisodeResult, float]]) -> dict[str, Any]:
    results = [r for r, _ in pairs]
    agg = aggregate(results)
    agg.update(
        censored_delay(
            [r.delay for r in results], [r.passed_crossing for r in results], [h for _, h in pairs]
        )
    )
    return agg


def _fmt(x: Any, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    if isinstance(x, float):
        return f"{x:.{digits}f}"
    return str(x)


def _row(name: str, agg: dict[str, Any]) -> list[str]:
    """The cells of one table row, in `TABLE_COLUMNS` order."""
    lo, hi = agg["collision_ci95"]
    comp = agg["yield_compliance"]
    return [
        name,
        str(agg["episodes"]),
        f"{agg['collision_rate']:.3f} [{lo:.3f}, {hi:.3f}]",
        f"{_fmt(agg['min_ttc_p5'])}/{_fmt(agg['min_ttc_p50'])}",
        _fmt(agg["pet_pedestrian_first_p5"]),
        _fmt(agg["drac_crossing_mean"]),
        _fmt(agg["hard_brakes_per_episode"]),
        f"{_fmt(comp, 3)} ({agg['yield_obligations']})",
        _fmt(agg["pass_rate"]),
        _fmt(agg["censored_mean_delay"]),
    ]


def format_table(summary: dict[str, Any], policies: Sequence[str]) -> str:
    """Fixed-width text table: one row per policy plus 'overall', then the world-health line."""
    rows = [[c for c, _ in TABLE_COLUMNS]]
    entries = [(p, summary["per_policy"][p]) for p in policies if p in summary["per_policy"]]
    entries.append(("overall", summary["overall"]))
    rows.extend(_row(name, agg) for name, agg in entries)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for i, row in enumerate(rows):
        lines.append(
            "  ".join(
                cell.ljust(w) if j == 0 else cell.rjust(w)
                for j, (cell, w) in enumerate(zip(row, widths, strict=True))
            )
        )
        if i == 0:
            lines.append("  ".join("-" * w for w in widths))
    lines.append(format_world_health(summary))
    return "\n".join(lines)


def format_world_health(summary: dict[str, Any]) -> str:
    """One line on the world around the ego: background car–pedestrian contacts (the ego is not involved)."""
    agg = summary["overall"]
    lo, hi = agg["background_collision_ci95"]
    return (
        f"world health: {agg['background_collisions']} background car-pedestrian contact(s)"
        f" ({agg['background_collisions_legal']} with a legal pedestrian) in {agg['episodes']} episodes;"
        f" episodes with one {agg['background_collision_rate']:.3f} [{lo:.3f}, {hi:.3f}];"
        f" max relative speed {_fmt(agg['background_collision_max_speed'])} m/s"
    )
