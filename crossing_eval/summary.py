"""Summaries of a run (per policy, per scenario and policy) and the printed table.

No figure pools different policies: a collision rate over several policies describes none of them. The
only number over every episode is the world-health line (background car–pedestrian contacts, which the
ego is not part of), kept apart from the table.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from crossing_env.safety import DEFAULT_METRICS, EpisodeResult
from crossing_eval.scoring import attach_scores, mean_interval
from crossing_eval.statistics import aggregate, censored_delay
from crossing_eval.tasks import EpisodeRecord
from scenarios import load_scenario

CLOSE_MARK = "!"
"""Appended to a table cell when some episode passed a pedestrian closer than `MetricsConfig.clearance`."""

_CFG = DEFAULT_METRICS


@dataclass(frozen=True)
class Column:
    """One table column: header, `aggregate` key (None if it combines several) and definition (report.md)."""

    header: str
    key: str | None
    definition: str
    same_as: str | None = None
    """The header of the full table's column whose cells this one shows (a shorter header for the
    headline table); None: its own cells."""


TABLE_COLUMNS: tuple[Column, ...] = (
    Column("policy", None, "The policy (one row each; rows never pool policies)."),
    Column("n", "episodes", "Episodes run (scenarios x episodes per scenario)."),
    Column(
        "score [95% CI]",
        None,
        "Mean episode score in [0, 1] with its 95% Student-t interval: gates for an at-fault collision, a"
        " broken or open yield obligation, too little progress against the careful reference driver"
        " (yielding) on the same seed and a near miss at speed, times a weighted mean of progress, TTC,"
        " speed limit and comfort (docs/results.md, 'The score'). Rows are sorted by it.",
    ),
    Column(
        "collision rate [95% CI]",
        None,
        "Fraction of episodes with any ego collision (pedestrian or vehicle), with its 95% Wilson score"
        " interval.",
    ),
    Column(
        "ped. at fault",
        "pedestrian_at_fault_collision_rate",
        "Fraction of episodes in which the ego hit a pedestrian and was at fault (nuPlan's rule: it hit with"
        " its front while both moved, or hit a pedestrian standing still; not when the ego stood still or"
        " was walked into from the side or behind).",
    ),
    Column(
        "veh. at fault",
        "vehicle_at_fault_collision_rate",
        "Fraction of episodes in which the ego hit a vehicle and was at fault (nuPlan's rule: a rear-end"
        " crash into a car ahead, moving or stopped; not when the ego stood still or was hit from behind).",
    ),
    Column(
        "min sep m (min/p50)",
        None,
        "Each episode's minimum ego-pedestrian footprint distance (box to disc, m; negative = overlap):"
        " the smallest over the episodes / their median. '-' = no pedestrian in any episode. A trailing"
        f" '{CLOSE_MARK}' marks a pass closer than the {_CFG.clearance:g} m clearance.",
    ),
    Column(
        "minTTC p5/p50 s",
        None,
        "Each episode's minimum ego-pedestrian time to collision (box-disc, constant velocities, not"
        " evaluated while the ego stands): 5th percentile / median over the episodes with a finite"
        " minimum. '-' = no episode was ever on a collision course, which is not the same as no conflict:"
        f" a trailing '{CLOSE_MARK}' says that some episode passed a pedestrian closer than"
        f" {_CFG.clearance:g} m all the same (see min sep), whatever the TTC.",
    ),
    Column(
        "PET p5 s",
        "pet_pedestrian_first_p5",
        "Post-encroachment time, pedestrian first: from a pedestrian leaving the conflict area (the ego's"
        " lane on the crossing) to the ego entering it; 5th percentile of the episode minima.",
    ),
    Column(
        f"DRAC>{_CFG.drac_threshold:g}",
        "drac_conflict_rate",
        "Deceleration rate to avoid a crash (DRAC, m/s²) against pedestrians holding the conflict area"
        " first: the constant braking that would bring the ego to the crossing just as they leave it. The"
        f" share of episodes in which it ever exceeded {_CFG.drac_threshold:g} m/s² (the usual conflict"
        " threshold, Archer 2005): the car needed harder than comfortable braking to avoid a pedestrian.",
    ),
    Column(
        "DRAC p95",
        "drac_crossing_p95",
        "95th percentile over episodes of each episode's maximum DRAC (m/s²), each capped at"
        f" {_CFG.drac_cap:g} m/s² (1 g, the most any car brakes): {_CFG.drac_cap:g} means one episode in"
        " twenty needed braking no car has. Uncapped, the figure runs to hundreds of m/s² near contact"
        " (results.json keeps drac_crossing_mean / _max so).",
    ),
    Column(
        "hard brakes/ep",
        "hard_brakes_per_episode",
        f"Hard-braking manoeuvres (runs of steps decelerating ≥ {_CFG.hard_braking_threshold:g} m/s²) per"
        " episode.",
    ),
    Column(
        "yield compl. (n)",
        None,
        "Yield obligations met / obligations (zebra, or signalised crossing on pedestrian green), and the"
        " number of obligations; '-' = none arose. Obligations still open when an episode ended count in"
        " the denominator, not as met (see unresolved).",
    ),
    Column(
        "unresolved",
        "yield_unresolved",
        "Yield obligations still open when their episode ended (the pedestrian had not cleared the ego's"
        " half, the ego had not entered the crossing): neither met nor broken, so they lower the"
        " compliance (a car that stops far from the crossing and waits, or one that crashed first).",
    ),
    Column(
        "over limit m/s",
        "max_speed_over_limit_max",
        "Speeding: the largest ego speed above the scenario's speed limit in any episode (m/s; 0 = never"
        " above).",
    ),
    Column(
        "over limit s/ep",
        "time_over_speed_limit_mean",
        "Speeding: time driven above the speed limit, mean per episode (s).",
    ),
    Column(
        "pass rate",
        "pass_rate",
        f"Fraction of episodes in which the ego centre reached {_CFG.delay_margin:g} m past the crossing's"
        " far edge (the delay target).",
    ),
    Column(
        "delay s (censored)",
        "censored_mean_delay",
        "Mean delay over all episodes. An episode's delay is the time from t = 0 until the ego centre"
        f" reaches the delay target ({_CFG.delay_margin:g} m past the crossing's far edge; linear"
        " interpolation between steps) minus the time that distance takes at the speed limit (negative"
        " = faster than the limit). Censoring: an episode that never reaches the target counts with a"
        " delay equal to its scenario's duration, so a policy that stops for good cannot look prompt.",
    ),
)
"""The full table's columns, in order (``crossing-eval --full-table``, ``table_full.txt``, ``report.md``)."""

SEPARATION_MARGIN = Column(
    "min sep p5 m",
    "min_separation_p5",
    "Separation margin: the 5th percentile over episodes of each episode's minimum ego-pedestrian footprint"
    " distance (m; negative = overlap): one episode in twenty passed closer. '-' = no pedestrian in any"
    f" episode; a trailing '{CLOSE_MARK}' says that some episode passed closer than the {_CFG.clearance:g} m"
    " clearance (as in the full table's min sep).",
)
_BY_HEADER = {c.header: c for c in TABLE_COLUMNS}
HEADLINE_COLUMNS: tuple[Column, ...] = (
    _BY_HEADER["policy"],
    _BY_HEADER["n"],
    _BY_HEADER["score [95% CI]"],
    _BY_HEADER["ped. at fault"],
    _BY_HEADER["yield compl. (n)"],
    SEPARATION_MARGIN,
    _BY_HEADER["pass rate"],
    Column(
        "delay s",
        "censored_mean_delay",
        "The headline table's name for 'delay s (censored)' (episodes that never pass count at the"
        " scenario's duration).",
        same_as="delay s (censored)",
    ),
)
"""The headline table `crossing-eval` prints (and ``table.txt``): the score first, then at-fault pedestrian
collisions, compliance, a separation margin, pass rate and delay; under `HEADLINE_WIDTH` columns."""
HEADLINE_WIDTH = 119
"""Widest line of the headline table and its notes (policy names up to 26 characters): a terminal of 120."""


def summarise(records: Sequence[EpisodeRecord], references: Sequence[EpisodeRecord] = ()) -> dict[str, Any]:
    """Per policy and per (scenario, policy) aggregates, and the world-health figures.

    Each aggregate (`crossing_eval.statistics.aggregate`) also holds the censored delay
    (`crossing_eval.statistics.censored_delay`): episodes that never pass count at their scenario's
    duration; and the episode score's mean and interval (``score_mean``, ``score_ci95``). Records not
    scored yet are scored here against the reference driver's episodes among `records` and `references`
    (`crossing_eval.scoring.attach_scores`; it raises when a seed's reference is missing). ``world_health``
    holds the background-contact figures over every episode of the run.
    """
    unscored = [r for r in records if r.score is None]
    if unscored:
        attach_scores(unscored, [*records, *references])
    horizons = {s: load_scenario(s).duration for s in {r.task.scenario for r in records}}
    results = [EpisodeResult.from_dict(r.result) for r in records]
    by_policy: dict[str, list[Any]] = {}
    by_pair: dict[str, list[Any]] = {}
    for rec, res in zip(records, results, strict=True):
        assert rec.score is not None  # attached above
        entry = (res, horizons[rec.task.scenario], rec.score["score"])
        by_policy.setdefault(rec.task.policy, []).append(entry)
        by_pair.setdefault(f"{rec.task.scenario}/{rec.task.policy}", []).append(entry)
    every = aggregate(results)
    return {
        "per_policy": {k: _aggregate(v) for k, v in by_policy.items()},
        "per_scenario_policy": {k: _aggregate(v) for k, v in sorted(by_pair.items())},
        "world_health": {k: v for k, v in every.items() if k == "episodes" or k.startswith("background_")},
    }


def _aggregate(entries: Sequence[tuple[EpisodeResult, float, float]]) -> dict[str, Any]:
    results = [r for r, _, _ in entries]
    agg = aggregate(results)
    agg.update(
        censored_delay(
            [r.delay for r in results], [r.passed_crossing for r in results], [h for _, h, _ in entries]
        )
    )
    mean, lo, hi = mean_interval([s for _, _, s in entries])
    agg["score_mean"], agg["score_ci95"] = mean, (lo, hi)
    return agg


def by_score(policies: Sequence[str], aggregates: dict[str, Any]) -> list[str]:
    """`policies` that have an aggregate, best mean score first (ties keep the given order)."""
    present = [p for p in policies if p in aggregates]
    return sorted(present, key=lambda p: -aggregates[p]["score_mean"])


def _fmt(x: Any, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    if isinstance(x, float):
        return f"{x:.{digits}f}"
    return str(x)


def _close(agg: dict[str, Any]) -> bool:
    """Some episode passed a pedestrian closer than the clearance."""
    sep = agg["min_separation_min"]
    return sep is not None and not math.isnan(sep) and sep < _CFG.clearance


def _row(name: str, agg: dict[str, Any], columns: Sequence[Column] = TABLE_COLUMNS) -> list[str]:
    """The cells of one table row, in `columns`' order."""
    cells = _cells(name, agg)
    return [cells[c.same_as or c.header] for c in columns]


def _cells(name: str, agg: dict[str, Any]) -> dict[str, str]:
    """Every cell of a policy's row, by column header (`TABLE_COLUMNS` and `SEPARATION_MARGIN`)."""
    lo, hi = agg["collision_ci95"]
    comp = agg["yield_compliance"]
    close = _close(agg)
    mark = CLOSE_MARK if close else ""
    sep = f"{_fmt(agg['min_separation_min'])}{mark}/{_fmt(agg['min_separation_p50'])}"
    # A close pass marks the TTC too: "-" (never on a collision course) or a long TTC is no all-clear.
    ttc = f"{_fmt(agg['min_ttc_p5'])}/{_fmt(agg['min_ttc_p50'])}{mark}"
    s_lo, s_hi = agg["score_ci95"]
    cells = [
        name,
        str(agg["episodes"]),
        f"{agg['score_mean']:.3f} [{s_lo:.3f}, {s_hi:.3f}]",
        f"{agg['collision_rate']:.3f} [{lo:.3f}, {hi:.3f}]",
        f"{agg['pedestrian_at_fault_collision_rate']:.3f}",
        f"{agg['vehicle_at_fault_collision_rate']:.3f}",
        sep,
        ttc,
        _fmt(agg["pet_pedestrian_first_p5"]),
        _fmt(agg["drac_conflict_rate"]),
        _fmt(agg["drac_crossing_p95"]),
        _fmt(agg["hard_brakes_per_episode"]),
        f"{_fmt(comp, 3)} ({agg['yield_obligations']})",
        str(agg["yield_unresolved"]),
        _fmt(agg["max_speed_over_limit_max"]),
        _fmt(agg["time_over_speed_limit_mean"]),
        _fmt(agg["pass_rate"]),
        _fmt(agg["censored_mean_delay"]),
    ]
    out = {c.header: cell for c, cell in zip(TABLE_COLUMNS, cells, strict=True)}
    out[SEPARATION_MARGIN.header] = f"{_fmt(agg['min_separation_p5'])}{mark}"  # the same '!' as min sep
    return out


def format_table(
    summary: dict[str, Any], policies: Sequence[str], columns: Sequence[Column] = TABLE_COLUMNS
) -> str:
    """Fixed-width text table, one row per policy (all scenarios of the run), best score first, two notes.

    `columns`: the full table by default, `HEADLINE_COLUMNS` for the narrow one. The notes are wrapped to
    the table's width or `HEADLINE_WIDTH`, whichever is wider.
    """
    rows = [[c.header for c in columns]]
    per_policy = summary["per_policy"]
    entries = [(p, per_policy[p]) for p in by_score(policies, per_policy)]
    rows.extend(_row(name, agg, columns) for name, agg in entries)
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
    where = (
        "every column is defined in report.md."
        if columns is TABLE_COLUMNS
        else "the full table (--full-table) and every column's definition are in report.md."
    )
    notes = [
        f"'{CLOSE_MARK}' = an episode passed a pedestrian closer than {_CFG.clearance:g} m; '-' = undefined;"
        f" delay: episodes that never pass count at the scenario's duration; {where}",
        format_world_health(summary),
    ]
    width = max(len(lines[0]), HEADLINE_WIDTH)
    lines.extend(part for note in notes for part in textwrap.wrap(note, width, break_on_hyphens=False))
    return "\n".join(lines)


def format_world_health(summary: dict[str, Any]) -> str:
    """One line on the world around the ego: background car–pedestrian contacts (the ego is not involved)."""
    agg = summary["world_health"]
    lo, hi = agg["background_collision_ci95"]
    return (
        f"world health: {agg['background_collisions']} background car-pedestrian contact(s)"
        f" ({agg['background_collisions_legal']} with a legal pedestrian) in {agg['episodes']} episodes;"
        f" episodes with one {agg['background_collision_rate']:.3f} [{lo:.3f}, {hi:.3f}];"
        f" max relative speed {_fmt(agg['background_collision_max_speed'])} m/s"
    )
