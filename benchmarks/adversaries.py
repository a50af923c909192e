"""Can a lazy or reckless driver look good? Each shipped adversary's score beside `yielding`'s, per scenario.

Runs `yielding` (the careful reference) and every adversary of `agents.adversaries.ADVERSARIES` on the same
seeds of every built-in scenario, through `crossing-eval`'s own tasks, runners and score, and reports per
scenario each one's mean score and its paired difference from `yielding`'s (the same seeds, so the
difference is taken episode by episode) with a 95 % Student-t interval. A score that cannot be fooled has
every adversary below `yielding` with the interval under 0 wherever the episodes tell them apart; the cells
where it is not are listed after the table, with the reason where it is known.

    python benchmarks/adversaries.py --episodes 20      # measure, write JSON and markdown
    python benchmarks/adversaries.py --render           # re-render the markdown from the JSON
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from agents.adversaries import ADVERSARIES
from crossing_common.files import write_text_atomic
from crossing_env.safety.score import REFERENCE_POLICY
from crossing_eval.provenance import source_commit
from crossing_eval.runners import default_workers, run_tasks
from crossing_eval.scoring import attach_scores
from crossing_eval.statistics import t_interval
from crossing_eval.tasks import make_tasks
from scenarios import list_scenarios

REPO = Path(__file__).resolve().parents[1]
DEFAULT_JSON = REPO / "benchmarks" / "results" / "adversaries.json"
BASE_SEED = 1058613806
"""Base seed of the suite: drawn with `secrets.randbelow(2**31)` when the suite was written, used nowhere
else in the project (the score was designed on other seeds, so it is not tuned to these episodes)."""


def paired_difference(adversary: list[float], reference: list[float]) -> tuple[float, float, float]:
    """Mean of the per-episode differences and its 95 % Student-t interval (`t_interval`)."""
    return t_interval(np.asarray(adversary, dtype=np.float64) - np.asarray(reference, dtype=np.float64))


def measure(scenarios: list[str], episodes: int, workers: int, progress: bool) -> dict[str, Any]:
    """Run the episodes and return the suite's data (scores by scenario and policy, in seed order)."""
    policies = [REFERENCE_POLICY, *ADVERSARIES]
    tasks = make_tasks(scenarios, policies, episodes, BASE_SEED)
    t0 = time.perf_counter()
    records = run_tasks(tasks, workers, show_progress=progress)
    wall = time.perf_counter() - t0
    attach_scores(records)
    scores: dict[str, dict[str, list[float]]] = defaultdict(dict)
    for r in sorted(records, key=lambda r: r.key):
        assert r.score is not None  # attached above
        scores[r.task.scenario].setdefault(r.task.policy, []).append(r.score["score"])
    cells: dict[str, dict[str, dict[str, float]]] = {}
    for sc in scenarios:
        ref = scores[sc][REFERENCE_POLICY]
        cells[sc] = {REFERENCE_POLICY: {"mean": float(np.mean(ref))}}
        for adv in ADVERSARIES:
            diff, lo, hi = paired_difference(scores[sc][adv], ref)
            cells[sc][adv] = {"mean": float(np.mean(scores[sc][adv])), "diff": diff, "low": lo, "high": hi}
    return {
        "command": "python benchmarks/adversaries.py " + " ".join(sys.argv[1:]),
        "commit": source_commit(),
        "episodes": episodes,
        "base_seed": BASE_SEED,
        "wall_seconds": round(wall, 1),
        "workers": workers,
        "adversaries": list(ADVERSARIES),
        "scenarios": cells,
    }


def misses(data: dict[str, Any]) -> list[str]:
    """One line per (scenario, adversary) not below `yielding` with the paired interval under 0."""
    out = []
    for sc, cells in data["scenarios"].items():
        for adv in data["adversaries"]:
            c = cells[adv]
            if not c["high"] < 0.0:
                out.append(
                    f"{sc} / {adv}: {c['mean']:.3f} against {cells[REFERENCE_POLICY]['mean']:.3f}, paired"
                    f" difference {c['diff']:+.3f} [{c['low']:+.3f}, {c['high']:+.3f}]"
                )
    return out


def render_body(data: dict[str, Any]) -> str:
    """The markdown block: one row per scenario, the reference's mean score, then each adversary's."""
    advs = data["adversaries"]
    header = ["scenario", REFERENCE_POLICY, *advs]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for sc, cells in data["scenarios"].items():
        row = [sc, f"{cells[REFERENCE_POLICY]['mean']:.3f}"]
        for adv in advs:
            c = cells[adv]
            mark = "" if c["high"] < 0.0 else " **!**"
            row.append(f"{c['mean']:.3f} ({c['diff']:+.2f} [{c['low']:+.2f}, {c['high']:+.2f}]){mark}")
        lines.append("| " + " | ".join(row) + " |")
    missed = misses(data)
    total = len(data["scenarios"]) * len(advs)
    summary = (
        f"Measured by `{data['command'].strip()}` on commit `{data['commit'][:12]}`:"
        f" {data['episodes']} episodes per scenario and policy, base seed {data['base_seed']}"
        f" ({data['wall_seconds']:.0f} s,"
        f" {data['workers']} workers). Each cell: the adversary's mean score (the paired difference from"
        f" {REFERENCE_POLICY} [95 % interval]); **!** marks a cell whose interval does not lie below 0."
        f" {total - len(missed)} of {total} cells below {REFERENCE_POLICY} with the interval under 0."
    )
    body = [summary, "", *lines]
    if missed:
        body += ["", "Not below:", "", *(f"- {m}" for m in missed)]
    return "\n".join(body)


def main(argv: list[str] | None = None) -> int:
    """Measure (or re-render) the suite; exit status 0 whether or not every adversary is below."""
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--episodes", type=int, default=20, help="episodes per scenario and policy")
    parser.add_argument("--scenarios", default=None, help="comma-separated scenarios (default: all built-in)")
    parser.add_argument("--workers", type=int, default=default_workers(), help="worker processes")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON, help="results file")
    parser.add_argument("--render", action="store_true", help="only print the block rendered from --json")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    args = parser.parse_args(argv)
    if args.render:
        data = json.loads(args.json.read_text(encoding="utf-8"))
    else:
        if args.episodes < 2 or args.workers < 1:
            parser.error("--episodes must be >= 2 (a paired interval needs two) and --workers >= 1")
        scenarios = sorted(list_scenarios()) if args.scenarios is None else args.scenarios.split(",")
        data = measure(scenarios, args.episodes, args.workers, not args.no_progress)
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(args.json, json.dumps(data, indent=1) + "\n")
    print(render_body(data))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
