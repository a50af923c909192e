"""Does each scenario tell careless from careful driving, and do its seeds differ? The discrimination report.

For every built-in scenario it runs the same seeds with a car that never brakes (`constant_speed`), the
rule-based `yielding` policy and `always_cautious`, through `crossing-eval`'s own tasks and runners (the
same seeds, wrappers and metrics as the table), and reports per scenario and policy:

- distinct outcomes: different (time to pass to 0.1 s, collision, min-TTC to 0.1 s, yield violations)
  tuples among the seeds (a scenario whose seeds all give the same episode measures one episode);
- pedestrian risk: the pedestrian collision rate, the violation rate (episodes with a failed yield
  obligation) and their union; collisions with vehicles (rear-end crashes into cars that stopped for
  pedestrians, at `busy_zebra`) are counted apart, with those the ego caused (`crossing_env.collision_fault`),
  and are not pedestrian risk;
- pass rate and the censored time to pass (an episode that never passes counts at the scenario's duration);
- the 5th percentile of the episodes' minimum TTC to a pedestrian.

It writes the numbers to a JSON file (with the commit and the command) and renders the markdown report from
that file, and checks the targets of a scenario that tests the car (printed, with the gaps):

    python benchmarks/discrimination.py --seeds 45              # measure, write JSON and markdown
    python benchmarks/discrimination.py --render                # re-render the markdown from the JSON
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

from crossing_common.files import write_text_atomic
from crossing_eval.provenance import source_commit
from crossing_eval.runners import default_workers, run_tasks
from crossing_eval.statistics import censored_delay
from crossing_eval.tasks import EpisodeRecord, make_tasks
from scenarios import list_scenarios, load_scenario

REPO = Path(__file__).resolve().parents[1]
POLICIES = ("constant_speed", "yielding", "always_cautious")
DEFAULT_JSON = REPO / "benchmarks" / "results" / "discrimination.json"
DEFAULT_MARKDOWN = REPO / "docs" / "scenario_discrimination.md"
BASE_SEED = 7000
"""Base seed of the report (not the table's 2024, so the report is not tuned on the table's episodes)."""
UNTARGETED = frozenset({"default"})
"""Scenarios not built around a conflict (free traffic): the careless-driver target does not apply."""


def _num(value: Any, missing: float) -> float:
    """A result field as a float; JSON-safe results hold None where the value is undefined or infinite."""
    return missing if value is None else float(value)


def outcome(result: dict[str, Any]) -> tuple[Any, ...]:
    """What distinguishes two episodes for the report (rounded so float noise does not count)."""
    ttp = _num(result["time_to_pass"], float("nan"))
    ttc = _num(result["min_ttc"], float("inf"))
    return (
        round(float(ttp), 1) if np.isfinite(ttp) else None,
        bool(result["collision"]),
        round(float(ttc), 1) if np.isfinite(ttc) else None,
        int(result["yield_violations"]),
    )


def _json_float(x: float) -> float | None:
    """JSON has no infinity: None stands for "no conflict" (an infinite minimum TTC)."""
    return x if np.isfinite(x) else None


def cell(records: list[EpisodeRecord], duration: float) -> dict[str, Any]:
    """The report's figures for one (scenario, policy)."""
    res = [r.result for r in records]
    collided = np.array([r["collision"] for r in res], dtype=bool)
    hit_pedestrian = np.array([r["pedestrian_collisions"] > 0 for r in res], dtype=bool)
    hit_vehicle = np.array([r["vehicle_collisions"] > 0 for r in res], dtype=bool)
    vehicle_fault = np.array([r["vehicle_collisions_at_fault"] > 0 for r in res], dtype=bool)
    violated = np.array([r["yield_violations"] > 0 for r in res], dtype=bool)
    passed = np.array([r["passed_crossing"] for r in res], dtype=bool)
    ttp = np.array([_num(r["time_to_pass"], float("nan")) for r in res], dtype=np.float64)
    censored = censored_delay(ttp, passed, duration)  # the table's rule: never passed → the duration
    ttc = np.array([_num(r["min_ttc"], float("inf")) for r in res], dtype=np.float64)
    return {
        "episodes": len(res),
        "distinct_outcomes": len({outcome(r) for r in res}),
        "collision_rate": float(collided.mean()),
        "pedestrian_collision_rate": float(hit_pedestrian.mean()),
        "vehicle_collision_rate": float(hit_vehicle.mean()),
        "vehicle_at_fault_collision_rate": float(vehicle_fault.mean()),
        "violation_rate": float(violated.mean()),
        "pedestrian_risk_rate": float((hit_pedestrian | violated).mean()),
        "pass_rate": censored["pass_rate"],
        "censored_time_to_pass": censored["censored_mean_delay"],
        "min_ttc_p5": _json_float(float(np.percentile(ttc, 5))),
    }


def measure(scenarios: list[str], seeds: int, workers: int, progress: bool) -> dict[str, Any]:
    """Run the episodes and return the report's data."""
    tasks = make_tasks(scenarios, list(POLICIES), seeds, BASE_SEED)
    t0 = time.perf_counter()
    records = run_tasks(tasks, workers, show_progress=progress)
    wall = time.perf_counter() - t0
    groups: dict[tuple[str, str], list[EpisodeRecord]] = defaultdict(list)
    for r in records:
        groups[(r.task.scenario, r.task.policy)].append(r)
    cells = {
        sc: {pol: cell(groups[(sc, pol)], load_scenario(sc).duration) for pol in POLICIES} for sc in scenarios
    }
    return {
        "command": "python benchmarks/discrimination.py " + " ".join(sys.argv[1:]),
        "commit": source_commit(),
        "seeds": seeds,
        "base_seed": BASE_SEED,
        "wall_seconds": round(wall, 1),
        "workers": workers,
        "scenarios": cells,
    }


def check_targets(data: dict[str, Any]) -> list[str]:
    """The targets a scenario that tests the car must meet; returns one line per miss."""
    misses = []
    n = data["seeds"]
    for sc, pols in data["scenarios"].items():
        careless, careful, cautious = pols["constant_speed"], pols["yielding"], pols["always_cautious"]
        risk = careless.get("pedestrian_risk_rate")  # absent from a JSON measured before it existed
        if sc not in UNTARGETED and risk is None:
            misses.append(f"{sc}: pedestrian risk not measured (regenerate the report)")
        elif sc not in UNTARGETED and risk < 0.5:
            misses.append(
                f"{sc}: constant_speed hits a pedestrian or fails to yield in"
                f" {careless['pedestrian_risk_rate']:.0%} of episodes (target >= 50 %)"
            )
        if careful["collision_rate"] > 0:
            misses.append(f"{sc}: yielding collides in {careful['collision_rate']:.0%} of episodes (want 0)")
        if careful["distinct_outcomes"] < round(35 / 45 * n):
            misses.append(
                f"{sc}: yielding has {careful['distinct_outcomes']} distinct outcomes out of {n}"
                f" (target >= {round(35 / 45 * n)})"
            )
        lo, hi = (0.2, 0.8) if sc == "busy_zebra" else (0.8, 1.0)
        if not lo <= careful["pass_rate"] <= hi:
            misses.append(f"{sc}: yielding passes in {careful['pass_rate']:.0%} (target {lo:.0%}-{hi:.0%})")
        if cautious["censored_time_to_pass"] <= careful["censored_time_to_pass"]:
            misses.append(f"{sc}: always_cautious is not slower than yielding")
    return misses


def _fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def render(data: dict[str, Any]) -> str:
    """The markdown page: a title and the report block between the results registry's markers."""
    return (
        "# Scenario discrimination report\n\n<!-- results:discrimination -->\n"
        + render_body(data)
        + "\n<!-- /results:discrimination -->\n"
    )


def render_body(data: dict[str, Any]) -> str:
    """The report from the JSON data (`python -m benchmarks.results` renders it, stale note included)."""
    lines = [
        "Generated by `python -m benchmarks.results discrimination` (which runs"
        " `benchmarks/discrimination.py`) from `benchmarks/results/discrimination.json`;"
        " do not edit by hand.",
        "",
        f"Measured on commit `{data['commit']}` with `{data['command'].strip()}`: {data['seeds']} seeds per"
        f" scenario (base seed {data['base_seed']}), {data['wall_seconds']:.0f} s on {data['workers']}"
        " worker(s). A scenario tells careless from careful driving when the car that never brakes"
        " (`constant_speed`) puts pedestrians at risk (hits one or fails to yield) and `yielding` does not;"
        " collisions with vehicles are shown apart (all, and those the ego caused: nuPlan's at-fault rule,"
        " docs/results.md) and are not pedestrian risk; its seeds differ when"
        " `yielding` meets many distinct outcomes (time to pass to 0.1 s, collision, min-TTC to 0.1 s,"
        " violations). Time to pass is censored: an episode that never passes counts at the duration.",
        "",
        "| scenario | policy | distinct | ped. collision | violation | ped. risk | veh. collision"
        " (at fault) | pass rate | time to pass (s) | min-TTC p5 (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for sc, pols in data["scenarios"].items():
        for pol, c in pols.items():
            lines.append(
                f"| {sc} | {pol} | {c['distinct_outcomes']}/{c['episodes']}"
                f" | {_fmt(c.get('pedestrian_collision_rate'))} | {_fmt(c['violation_rate'])}"
                f" | {_fmt(c.get('pedestrian_risk_rate'))} | {_fmt(c.get('vehicle_collision_rate'))}"
                f" ({_fmt(c.get('vehicle_at_fault_collision_rate'))}) | {_fmt(c['pass_rate'])}"
                f" | {_fmt(c['censored_time_to_pass'], 1)}"
                f" | {_fmt(c['min_ttc_p5'])} |"
            )
    crashes = [
        f"{sc} / {pol}: {_fmt(c['vehicle_collision_rate'])} of episodes"
        f" ({_fmt(c['vehicle_at_fault_collision_rate'])} at fault)"
        for sc, pols in data["scenarios"].items()
        for pol, c in pols.items()
        if c.get("vehicle_collision_rate")
    ]
    lines += [
        "",
        "Collisions with vehicles, which are not pedestrian risk (a car that crashes into the car ahead"
        " before the crossing never gets to endanger the people on it; its obligations to them stay"
        " unresolved): " + ("; ".join(crashes) if crashes else "none") + ".",
    ]
    misses = check_targets(data)
    lines += ["", "## Targets", ""]
    lines.append(
        "Per scenario: `constant_speed` hits a pedestrian or fails to yield in >= 50 % of episodes"
        " (scenarios built around a conflict); `yielding` never collides with anything, has >= 35 distinct"
        " outcomes in 45 seeds and passes in >= 80 % of episodes (`busy_zebra`: 20-80 %); `always_cautious`"
        " is slower than `yielding`."
    )
    lines.append("")
    lines += [f"- missed: {m}" for m in misses] if misses else ["All targets met."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Measure (or re-render) the report; exit status 0 whether or not the targets are met."""
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=45, help="episodes per scenario and policy")
    parser.add_argument("--scenarios", default=None, help="comma-separated scenarios (default: all built-in)")
    parser.add_argument("--workers", type=int, default=default_workers(), help="worker processes")
    parser.add_argument("--json", type=Path, default=DEFAULT_JSON, help="results file")
    parser.add_argument("--markdown", type=Path, default=DEFAULT_MARKDOWN, help="rendered report")
    parser.add_argument("--render", action="store_true", help="only re-render the markdown from --json")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    args = parser.parse_args(argv)
    if args.render:
        data = json.loads(args.json.read_text(encoding="utf-8"))
    else:
        if args.seeds < 1 or args.workers < 1:
            parser.error("--seeds and --workers must be >= 1")
        scenarios = sorted(list_scenarios()) if args.scenarios is None else args.scenarios.split(",")
        data = measure(scenarios, args.seeds, args.workers, not args.no_progress)
        args.json.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(args.json, json.dumps(data, indent=1) + "\n")
    text = render(data)
    write_text_atomic(args.markdown, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
