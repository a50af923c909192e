"""The report: ``report.md`` (per-policy and per-scenario tables, column definitions) and its CSV rows.

The printed table pools every scenario per policy (never policies); the scenario x policy numbers are
what a reader compares policies on, so they get their own table. Custom scenario files are named by
the scenario's ``name`` field, not their path. Missing values are one convention everywhere: "-" in
text and Markdown, an empty cell in CSV, ``null`` in JSON.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from crossing_eval.summary import HEADLINE_COLUMNS, TABLE_COLUMNS, _row, by_score, format_world_health
from scenarios import load_scenario

SCENARIO_CSV_FIELDS = (
    "episodes",
    "score_mean",
    "collision_rate",
    "pedestrian_collision_rate",
    "pedestrian_at_fault_collision_rate",
    "vehicle_collision_rate",
    "vehicle_at_fault_collision_rate",
    "min_separation_min",
    "min_separation_p50",
    "close_pass_rate",
    "min_ttc_p5",
    "min_ttc_p50",
    "serious_conflict_rate",
    "pet_pedestrian_first_p5",
    "drac_crossing_mean",
    "hard_brakes_per_episode",
    "yield_obligations",
    "yield_compliance",
    "yield_unresolved",
    "speeding_rate",
    "max_speed_over_limit_max",
    "time_over_speed_limit_mean",
    "pass_rate",
    "mean_delay",
    "censored_mean_delay",
    "censored_episodes",
)
"""Columns of ``per_scenario.csv`` after scenario and policy (keys of the aggregates), then the CI."""
RESULTS_DOC = "docs/results.md"
"""The page that defines every field of ``results.json`` and every column; report.md points to it."""


def scenario_labels(scenarios: Sequence[str]) -> dict[str, str]:
    """Display name of each scenario argument: its ``name`` field, or the argument when names clash."""
    names = {s: load_scenario(s).name or Path(s).stem for s in scenarios}
    counts: dict[str, int] = {}
    for n in names.values():
        counts[n] = counts.get(n, 0) + 1
    return {s: (n if counts[n] == 1 else s) for s, n in names.items()}


def csv_cell(x: Any) -> Any:
    """One CSV cell: missing or undefined (None, nan) → empty, ±inf → "inf"/"-inf", else the value."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    if isinstance(x, float) and math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return x


def per_scenario_rows(
    summary: Mapping[str, Any], labels: Mapping[str, str], policies: Sequence[str]
) -> tuple[list[str], list[list[Any]]]:
    """Header and rows of ``per_scenario.csv``: one row per (scenario, policy), in label then policy order."""
    header = ["scenario", "policy", *SCENARIO_CSV_FIELDS, "collision_ci95_low", "collision_ci95_high"]
    rows = []
    for scenario, policy, agg in _pairs(summary, labels, policies):
        lo, hi = agg["collision_ci95"]
        rows.append([scenario, policy, *(csv_cell(agg[k]) for k in SCENARIO_CSV_FIELDS), lo, hi])
    return header, rows


def _pairs(
    summary: Mapping[str, Any], labels: Mapping[str, str], policies: Sequence[str]
) -> list[tuple[str, str, dict[str, Any]]]:
    out = []
    for key, agg in summary["per_scenario_policy"].items():
        scenario, policy = key.rsplit("/", 1)
        out.append((labels.get(scenario, scenario), policy, agg))
    order = {p: i for i, p in enumerate(policies)}
    return sorted(out, key=lambda t: (t[0], order.get(t[1], len(order)), t[1]))


def _markdown(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    esc = [[c.replace("|", "\\|") for c in r] for r in (header, *rows)]
    lines = ["| " + " | ".join(esc[0]) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(r) + " |" for r in esc[1:])
    return "\n".join(lines)


def report_markdown(
    summary: Mapping[str, Any],
    policies: Sequence[str],
    labels: Mapping[str, str],
    settings: Mapping[str, Any],
    extra_sections: str = "",
) -> str:
    """``report.md``: the settings, the per-policy table, one table per scenario, the column definitions.

    `extra_sections` (markdown, e.g. the NCAP-style scoring) goes after the world-health line.
    """
    header = [c.header for c in TABLE_COLUMNS]
    per_policy = [_row(p, summary["per_policy"][p]) for p in by_score(policies, summary["per_policy"])]
    used = ", ".join(settings.get("predictors_used") or []) or "none"
    parts = [
        "# crossing-eval report",
        "",
        f"{settings.get('episodes')} episode(s) per scenario and policy, base seed {settings.get('seed')},"
        f" predictor {settings.get('predictor')}, intention {settings.get('intention')} (for the policies"
        f" that read predictions); wrappers that actually ran: {used}.",
        "One row per policy, best mean score first; no row pools different policies. The columns are"
        " defined at the end ('-' = undefined).",
        "",
        "## Per policy, all scenarios of the run",
        "",
        _markdown(header, per_policy),
    ]
    by_scenario: dict[str, dict[str, Any]] = {}
    for scenario, policy, agg in _pairs(summary, labels, policies):
        by_scenario.setdefault(scenario, {})[policy] = agg
    for scenario, aggs in by_scenario.items():
        rows = [_row(p, aggs[p]) for p in by_score(list(aggs), aggs)]
        parts += ["", f"## {scenario}", "", _markdown(header, rows)]
    parts += ["", "## World health", "", format_world_health(summary) + "."]
    if extra_sections:
        parts += ["", extra_sections.rstrip("\n")]
    parts += ["", "## Definitions", "", *definitions_markdown()]
    return "\n".join(parts) + "\n"


def definitions_markdown() -> list[str]:
    """The definitions section: one bullet per column of the full and the headline table."""
    headline_only = [c for c in HEADLINE_COLUMNS if c not in TABLE_COLUMNS]
    lines = [f"- **{c.header}**: {c.definition}" for c in (*TABLE_COLUMNS, *headline_only)]
    lines.append(
        "- **world health**: contacts between background cars and pedestrians over every episode of the run"
        " (the ego is not involved), with the fraction of episodes that had one (95% Wilson interval)."
    )
    lines.append(
        "- Percentiles are over episodes (one value per episode: its minimum or maximum); 95% intervals"
        " are Wilson score intervals; `per_scenario.csv` and `summary.csv` hold the same figures unrounded"
        " (an empty cell = undefined, `inf` = never)."
    )
    lines.append(
        "- Every field of `results.json` and how each column recomputes from its episode records (the"
        f" censoring rule included): `{RESULTS_DOC}` in the crossing-env source."
    )
    return lines
