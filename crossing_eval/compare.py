"""`crossing-eval compare DIR_A DIR_B`: what changed between two runs, with 95% intervals.

For every (scenario, policy) in both runs, and per policy pooled: collision rate and pass rate
(differences with Newcombe's interval, `crossing_eval.statistics.newcombe_difference`) and the censored
delay (difference of means with Welch's interval from `scipy.stats.ttest_ind`). Rows are B − A.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from crossing_common.cli import DefaultsHelpFormatter
from crossing_eval.statistics import newcombe_difference
from scenarios import ScenarioError, load_scenario


class RunError(ValueError):
    """A results folder that cannot be compared; the message names the file and why."""


def load_run(folder: Path) -> dict[str, Any]:
    """The ``results.json`` of a crossing-eval output folder.

    Raises:
        RunError: missing, unreadable or not a crossing-eval results file.
    """
    path = folder / "results.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise RunError(
            f"{path}: cannot read ({exc.strerror or exc}); is {folder} a crossing-eval output?"
        ) from None
    except json.JSONDecodeError as exc:
        raise RunError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("episodes"), list):
        raise RunError(f"{path}: no 'episodes' list; not a crossing-eval results file")
    return doc


def _groups(doc: dict[str, Any]) -> dict[tuple[str, str], list[dict[str, Any]]]:
    names = doc.get("settings", {}).get("scenario_names", {})
    out: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for ep in doc["episodes"]:
        scenario = ep.get("scenario_name") or names.get(ep["scenario"], ep["scenario"])
        out.setdefault((scenario, ep["policy"]), []).append(ep)
        out.setdefault(("(all)", ep["policy"]), []).append(ep)
    return out


def _censored(ep: dict[str, Any], horizon: float) -> float:
    m = ep["metrics"]
    d = m.get("delay")
    return float(d) if m.get("passed_crossing") and d is not None else horizon


def _horizons(doc: dict[str, Any]) -> dict[str, float]:
    """Each scenario's duration used for censoring.

    The run's own record (``provenance.scenario_durations``), else the scenario file, else the longest
    episode seen (a run written before durations were recorded).
    """
    out: dict[str, float] = {}
    for ep in doc["episodes"]:
        out[ep["scenario"]] = max(out.get(ep["scenario"], 0.0), float(ep["metrics"].get("duration") or 0.0))
    recorded = doc.get("settings", {}).get("provenance", {}).get("scenario_durations", {})
    for name in out:
        if name in recorded:
            out[name] = float(recorded[name])
            continue
        try:
            out[name] = load_scenario(name).duration
        except ScenarioError:
            pass
    return out


def _rate_cell(a: list[bool], b: list[bool]) -> str:
    diff, lo, hi = newcombe_difference(sum(a), len(a), sum(b), len(b))
    return f"{sum(a) / len(a):.2f}→{sum(b) / len(b):.2f} {diff:+.2f} [{lo:+.2f}, {hi:+.2f}]"


def _mean_cell(a: list[float], b: list[float], paired: bool) -> str:
    """Means A→B, difference, and its 95% interval: paired t when the episodes share seeds, else Welch t."""
    from scipy import stats

    ma, mb = float(np.mean(a)), float(np.mean(b))
    text = f"{ma:.2f}→{mb:.2f} {mb - ma:+.2f}"
    diff = np.asarray(b) - np.asarray(a) if paired else None
    if diff is not None and np.ptp(diff) == 0:
        return text + f" [{diff[0]:+.2f}, {diff[0]:+.2f}]"  # every pair moved by the same amount
    if len(a) >= 2 and len(b) >= 2 and (np.ptp(a) > 0 or np.ptp(b) > 0):
        test = stats.ttest_rel(b, a) if paired else stats.ttest_ind(b, a, equal_var=False)
        ci = test.confidence_interval(0.95)
        return text + f" [{ci.low:+.2f}, {ci.high:+.2f}]"
    return text + " [-]"


def _paired(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> bool:
    """Whether both runs hold the same episodes (same seeds, same order): a paired comparison."""
    return [(e["scenario"], e["episode"], e["seed"]) for e in a] == [
        (e["scenario"], e["episode"], e["seed"]) for e in b
    ]


def compare(doc_a: dict[str, Any], doc_b: dict[str, Any]) -> str:
    """The comparison table (text) of two runs' results; rows present in only one run are listed below it."""
    ga, gb = _groups(doc_a), _groups(doc_b)
    ha, hb = _horizons(doc_a), _horizons(doc_b)
    header = ["scenario", "policy", "n A/B", "collision rate B−A [95% CI]", "pass rate", "delay s (cens.)"]
    rows = [header]
    for key in sorted(set(ga) & set(gb), key=lambda k: (k[0] == "(all)", k)):
        a, b = ga[key], gb[key]
        rows.append(
            [
                key[0],
                key[1],
                f"{len(a)}/{len(b)}",
                _rate_cell([e["metrics"]["collision"] for e in a], [e["metrics"]["collision"] for e in b]),
                _rate_cell(
                    [bool(e["metrics"]["passed_crossing"]) for e in a],
                    [bool(e["metrics"]["passed_crossing"]) for e in b],
                ),
                _mean_cell(
                    [_censored(e, ha[e["scenario"]]) for e in a],
                    [_censored(e, hb[e["scenario"]]) for e in b],
                    _paired(a, b),
                ),
            ]
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    for name, mine, other in (("A", ga, gb), ("B", gb, ga)):
        only = {p for s, p in set(mine) - set(other)}
        if only:
            lines.append("")
            lines.append(f"policies only in run {name} (not compared): {', '.join(sorted(only))}")
    lines.append("")
    lines.append(
        "cells: A→B, difference B−A, 95% CI (rates: Newcombe; delay: paired t when both runs ran the same"
        " seeds, else Welch t)"
    )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``crossing-eval compare``; 0 ok, 2 for a folder that is not a results folder."""
    parser = argparse.ArgumentParser(
        prog="crossing-eval compare",
        description="Print the differences between two crossing-eval runs (B − A) with 95% intervals.",
        formatter_class=DefaultsHelpFormatter,
    )
    parser.add_argument("dir_a", type=Path, help="output folder of the first run (A)")
    parser.add_argument("dir_b", type=Path, help="output folder of the second run (B)")
    args = parser.parse_args(argv)
    try:
        doc_a, doc_b = load_run(args.dir_a), load_run(args.dir_b)
    except RunError as exc:
        print(f"crossing-eval compare: error: {exc}", file=sys.stderr)
        return 2
    print(compare(doc_a, doc_b))
    return 0


__all__ = ["RunError", "compare", "load_run", "main"]
