"""`docs/results.md` is the contract of `results.json`: every key defined there, every column recomputed.

A small run (three scenarios, two policies, two episodes) is recomputed from its episode records alone,
following the page's rules and nothing from `crossing_eval`: every aggregate key, every cell of the
printed table and of each `report.md` table, and the world-health line. Two of the scenarios are
shortened copies of built-in ones, so that the run holds the cases the rules are about: collision
episodes that never passed (censored at the scenario's duration, not at their length), episodes stopped by
the time limit, and an episode whose rear cleared the crossing without reaching the delay target.
"""

from __future__ import annotations

import copy
import json
import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats

import crossing_eval.cli as cli
from scenarios import BUILTIN_DIR

DOC = Path(__file__).resolve().parents[2] / "docs" / "results.md"
CLEARANCE = 1.0
"""m: the clearance the page names (min sep '!', close_pass_rate)."""
SERIOUS_TTC = 1.5
"""s: the serious-conflict TTC the page names."""
CRITICAL_PET = 1.5
"""s: the critical PET the page names."""
DRAC_THRESHOLD = 3.35
"""m/s²: the DRAC conflict threshold the page names."""
DRAC_CAP = 9.81
"""m/s²: the cap (1 g) on each episode's maximum DRAC the page names."""
DURATIONS = {"cut_zebra": 7.5, "short_occluded": 12.0}
"""The shortened scenarios' durations (s): their time limits, so the censoring value differs per scenario."""

Episode = dict[str, Any]


def _variant(source: str, name: str, folder: Path, **values: float) -> str:
    """A built-in scenario file with a new name and some top-level or table fields replaced."""
    text = (BUILTIN_DIR / f"{source}.toml").read_text()
    text, count = re.subn(r'^name = ".*"$', f'name = "{name}"', text, count=1, flags=re.M)
    assert count == 1
    for key, value in values.items():
        text, count = re.subn(rf"^{key} = [^#\n]*", f"{key} = {value}", text, count=1, flags=re.M)
        assert count == 1, key
    path = folder / f"{name}.toml"
    path.write_text(text)
    return str(path)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("schema")
    # The time limit falls just after a 12 m/s car's rear clears the zebra (speed limit lowered, so there
    # is speeding too); the occluded pedestrian is hit before the crossing well inside 12 s.
    cut = _variant("zebra_case1", "cut_zebra", folder, duration=DURATIONS["cut_zebra"], speed_limit=11.5)
    short = _variant("occluded_parked_car", "short_occluded", folder, duration=DURATIONS["short_occluded"])
    out = folder / "out"
    argv = ["--scenarios", f"{cut},{short},children_running", "--policies", "constant_speed,ttc_brake"]
    argv += ["--episodes", "2", "--workers", "1", "--no-progress", "--out", str(out)]
    assert cli.main(argv) == 0
    return out


@pytest.fixture(scope="module")
def doc(run: Path) -> dict[str, Any]:
    return json.loads((run / "results.json").read_text())


# ---------------------------------------------------------------------------------------------------------
# Every key is documented
# ---------------------------------------------------------------------------------------------------------

MAPS = {
    "settings.scenario_names": "<scenario>",
    "settings.provenance.scenario_durations": "<scenario>",
    "settings.provenance.files": "<file>",
    "summary.per_policy": "<policy>",
    "summary.per_scenario_policy": "<scenario>/<policy>",
}
"""Objects keyed by data (scenario, file, policy), and the placeholder the page writes for the key."""
AGGREGATES = {"summary.per_policy.<policy>", "summary.per_scenario_policy.<scenario>/<policy>"}
"""Aggregates, whose keys the page lists once as ``<aggregate>.KEY``."""


def schema_paths(value: Any, path: str = "") -> set[str]:
    """Every key of a results document as the page writes it: ``episodes[].metrics.delay``, ..."""
    out = {path} if path else set()
    if isinstance(value, dict):
        for key, item in value.items():
            if path in MAPS:
                child = f"{path}.{MAPS[path]}"
            elif path == "reference_episodes[]":  # the keys of `episodes[]`, documented there
                child = f"episodes[].{key}"
            elif path in AGGREGATES:
                child = f"<aggregate>.{key}"
            else:
                child = f"{path}.{key}" if path else key
            out |= schema_paths(item, child)
    elif isinstance(value, list) and value and all(isinstance(x, dict) for x in value):
        for item in value:
            out |= schema_paths(item, f"{path}[]")
    return out


def documented() -> set[str]:
    """The keys the page defines: the first cell of a row of one of its key tables."""
    return set(re.findall(r"^\| `([^`\n]+)` \|", DOC.read_text(), flags=re.M))


def test_every_key_of_results_json_is_documented(doc: dict[str, Any]) -> None:
    paths = schema_paths(doc)
    assert {"settings.provenance.scenario_durations.<scenario>", "<aggregate>.censored_mean_delay"} <= paths
    assert "episodes[].metrics.time_to_pass" in paths
    missing = sorted(paths - documented())
    assert not missing, f"results.json keys without a definition in docs/results.md: {missing}"


def test_a_new_key_without_a_definition_is_caught(doc: dict[str, Any]) -> None:
    doc = copy.deepcopy(doc)
    doc["summary"]["per_policy"]["ttc_brake"]["brand_new_rate"] = 0.5
    doc["episodes"][0]["metrics"]["brand_new_field"] = 1
    missing = schema_paths(doc) - documented()
    assert missing == {"<aggregate>.brand_new_rate", "episodes[].metrics.brand_new_field"}


def test_every_documented_key_exists(doc: dict[str, Any]) -> None:
    """The page lists no key that results.json does not have (a removed field must leave the page too)."""
    listed = documented()
    assert len(listed) > 100
    # No model file is loaded by these two policies, so `files` is an empty object here.
    assert doc["settings"]["provenance"]["files"] == {}
    absent = listed - schema_paths(doc) - {"settings.provenance.files.<file>"}
    assert not absent, f"docs/results.md defines keys results.json does not have: {sorted(absent)}"


def test_provenance_holds_the_censoring_durations(doc: dict[str, Any]) -> None:
    prov = doc["settings"]["provenance"]
    expected = {}
    for scenario in doc["settings"]["scenarios"]:
        if scenario.endswith(".toml"):
            expected[scenario] = DURATIONS[Path(scenario).stem]
        else:
            text = (BUILTIN_DIR / f"{scenario}.toml").read_text()
            match = re.search(r"^duration = ([0-9.]+)", text, flags=re.M)
            assert match is not None, scenario
            expected[scenario] = float(match.group(1))
    assert prov["scenario_durations"] == expected
    assert re.fullmatch(r"[0-9a-f]{40}(-dirty)?|unknown", prov["commit"])
    assert prov["package_version"] and prov["python"]
    assert prov["command"].startswith("crossing-eval --scenarios ") and "--workers" not in prov["command"]


# ---------------------------------------------------------------------------------------------------------
# Recomputing from the episode records, by the page's rules
# ---------------------------------------------------------------------------------------------------------


def wilson(k: int, n: int, z: float = 1.96) -> list[float]:
    if n == 0:
        return [0.0, 1.0]
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n)) / denom
    return [0.0 if k == 0 else centre - half, 1.0 if k == n else centre + half]


def values(eps: Sequence[Episode], key: str) -> list[float]:
    """The non-null values of a metric (null = never or undefined: left out either way)."""
    return [e["metrics"][key] for e in eps if e["metrics"][key] is not None]


def pct(eps: Sequence[Episode], key: str, q: float) -> float | None:
    finite = values(eps, key)
    return float(np.percentile(finite, q)) if finite else None


def capped_p95(eps: Sequence[Episode], key: str, cap: float) -> float | None:
    """95th percentile of the non-null values, each capped at `cap` (an infinite one counts as `cap`)."""
    capped = [min(float(e["metrics"][key]), cap) for e in eps if e["metrics"][key] is not None]
    return float(np.percentile(capped, 95)) if capped else None


def mean(xs: Sequence[float]) -> float | None:
    return float(np.mean(xs)) if xs else None


def share(eps: Sequence[Episode], test: Callable[[dict[str, Any]], bool]) -> float:
    return sum(bool(test(e["metrics"])) for e in eps) / len(eps)


def total(eps: Sequence[Episode], key: str) -> int:
    return sum(e["metrics"][key] for e in eps)


def largest(eps: Sequence[Episode], key: str) -> float | None:
    finite = values(eps, key)
    return max(finite) if finite else None


def censored(ep: Episode, durations: dict[str, float]) -> float:
    """The page's rule: the delay if the ego passed, else the scenario's duration (collisions included)."""
    m = ep["metrics"]
    return m["delay"] if m["passed_crossing"] else durations[ep["scenario"]]


def share_below(eps: Sequence[Episode], key: str, limit: float) -> float:
    """Share with a value below `limit`; null (never) does not count."""
    return share(eps, lambda m: m[key] is not None and m[key] < limit)


def score_of(m: dict[str, Any], ref: dict[str, Any]) -> float:
    """An episode's score from its metrics and the reference's, as docs/results.md ("The score") says."""

    def progress(x: dict[str, Any]) -> float:
        if not x["passed_crossing"]:
            return 0.0
        return min(1.0, (x["target_time"] - x["delay"]) / x["target_time"])

    if ref["passed_crossing"]:
        gate = progress(m) >= 0.2 * progress(ref)
    elif m["passed_crossing"] or ref["distance_travelled"] < 5.0:
        gate = True
    else:
        gate = m["distance_travelled"] >= 0.2 * ref["distance_travelled"]
    ped = 0.0 if m["pedestrian_collisions_at_fault"] else 1.0
    veh = 0.0 if m["vehicle_collisions_at_fault"] else 0.5 if m["static_collisions"] else 1.0
    yld = 0.0 if m["yield_violations"] else 0.5 if m["yield_unresolved"] else 1.0
    ttc = 1.0 if m["min_ttc"] is None else min(1.0, m["min_ttc"] / 1.5)
    speed = max(0.0, 1.0 - m["max_speed_over_limit"] / 2.23)
    comfort = 1.0 - min(1.0, max(0.0, (m["max_deceleration"] - 4.05) / (8.0 - 4.05)))
    weighted = (5 * progress(m) + 5 * ttc + 4 * speed + 2 * comfort) / 16
    return ped * veh * yld * float(gate) * (1.0 - m["near_miss"]) * weighted


def score_interval(scores: Sequence[float]) -> tuple[float, list[float]]:
    """Mean and its 95 % Student-t interval clipped to [0, 1], as the page says."""
    m = float(np.mean(scores))
    if len(scores) < 2 or float(np.std(scores)) == 0.0:
        return m, [m, m]
    half = stats.t.ppf(0.975, len(scores) - 1) * float(np.std(scores, ddof=1)) / math.sqrt(len(scores))
    return m, [max(0.0, m - half), min(1.0, m + half)]


def recompute(eps: Sequence[Episode], durations: dict[str, float]) -> dict[str, Any]:
    """Every aggregate key from the records, as docs/results.md defines it."""
    n = len(eps)
    score_mean, score_ci95 = score_interval([e["score"]["score"] for e in eps])
    coll = sum(e["metrics"]["collision"] for e in eps)
    ped = sum(e["metrics"]["pedestrian_collisions"] > 0 for e in eps)
    ped_fault = sum(e["metrics"]["pedestrian_collisions_at_fault"] > 0 for e in eps)
    veh = sum(e["metrics"]["vehicle_collisions"] > 0 for e in eps)
    veh_fault = sum(e["metrics"]["vehicle_collisions_at_fault"] > 0 for e in eps)
    bg = sum(e["metrics"]["background_collisions"] > 0 for e in eps)
    compliant, obligations = total(eps, "yield_compliant"), total(eps, "yield_obligations")

    def min_pet(m: dict[str, Any]) -> bool:
        pets = [m[k] for k in ("min_pet_pedestrian_first", "min_pet_ego_first") if m[k] is not None]
        return bool(pets) and min(pets) < CRITICAL_PET

    def avg(key: str) -> float | None:
        return mean(values(eps, key))

    return {
        "episodes": n,
        "score_mean": score_mean,
        "score_ci95": score_ci95,
        "collision_rate": coll / n,
        "collision_ci95": wilson(coll, n),
        "pedestrian_collision_rate": ped / n,
        "pedestrian_collision_ci95": wilson(ped, n),
        "pedestrian_at_fault_collision_rate": ped_fault / n,
        "pedestrian_at_fault_collision_ci95": wilson(ped_fault, n),
        "vehicle_collision_rate": veh / n,
        "vehicle_at_fault_collision_rate": veh_fault / n,
        "vehicle_at_fault_collision_ci95": wilson(veh_fault, n),
        "static_collisions": total(eps, "static_collisions"),
        "compliant_pedestrian_collisions": total(eps, "compliant_pedestrian_collisions"),
        "noncompliant_pedestrian_collisions": total(eps, "noncompliant_pedestrian_collisions"),
        "mean_impact_speed": avg("max_impact_speed"),
        "min_ttc_p5": pct(eps, "min_ttc", 5),
        "min_ttc_p50": pct(eps, "min_ttc", 50),
        "min_ttc_finite_fraction": len(values(eps, "min_ttc")) / n,
        "serious_conflict_rate": share_below(eps, "min_ttc", SERIOUS_TTC),
        "min_separation_min": pct(eps, "min_separation", 0),
        "min_separation_p5": pct(eps, "min_separation", 5),
        "min_separation_p50": pct(eps, "min_separation", 50),
        "close_pass_rate": share_below(eps, "min_separation", CLEARANCE),
        "pet_pedestrian_first_p5": pct(eps, "min_pet_pedestrian_first", 5),
        "pet_pedestrian_first_p50": pct(eps, "min_pet_pedestrian_first", 50),
        "pet_ego_first_p5": pct(eps, "min_pet_ego_first", 5),
        "pet_ego_first_p50": pct(eps, "min_pet_ego_first", 50),
        "critical_pet_rate": share(eps, min_pet),
        "simultaneous_occupancies": total(eps, "simultaneous_occupancies"),
        "drac_conflict_rate": share(eps, lambda m: m["max_drac_crossing"] > DRAC_THRESHOLD),
        "drac_crossing_p95": capped_p95(eps, "max_drac_crossing", DRAC_CAP),
        "drac_crossing_mean": avg("max_drac_crossing"),
        "drac_crossing_max": largest(eps, "max_drac_crossing"),
        "drac_following_max": largest(eps, "max_drac_following"),
        "hard_brakes_per_episode": avg("hard_braking_events"),
        "comfort_violations_per_episode": avg("comfort_violation_steps"),
        "max_deceleration_mean": avg("max_deceleration"),
        "speeding_rate": share(eps, lambda m: m["time_over_speed_limit"] > 0),
        "max_speed_over_limit_max": largest(eps, "max_speed_over_limit"),
        "max_speed_over_limit_mean": avg("max_speed_over_limit"),
        "time_over_speed_limit_mean": avg("time_over_speed_limit"),
        "yield_obligations": obligations,
        "yield_compliance": compliant / obligations if obligations else None,
        "yield_compliance_ci95": wilson(compliant, obligations),
        "yield_unresolved": total(eps, "yield_unresolved"),
        "unneeded_stops_per_episode": avg("unneeded_stops"),
        "pass_rate": share(eps, lambda m: m["passed_crossing"]),
        "mean_delay": avg("delay"),
        "censored_mean_delay": float(np.mean([censored(e, durations) for e in eps])),
        "censored_episodes": sum(not e["metrics"]["passed_crossing"] for e in eps),
        "mean_time_to_pass": avg("time_to_pass"),
        "mean_pedestrian_wait": mean([w for e in eps for w in e["metrics"]["pedestrian_wait_times"]]),
        "mean_distance": avg("distance_travelled"),
        "background_collisions": total(eps, "background_collisions"),
        "background_collisions_legal": total(eps, "background_collisions_legal"),
        "background_collision_rate": bg / n,
        "background_collision_ci95": wilson(bg, n),
        "background_collision_max_speed": largest(eps, "background_collision_max_speed"),
    }


def fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def row(policy: str, agg: dict[str, Any]) -> list[str]:
    """The table's cells, as the page's column table says."""
    close = agg["min_separation_min"] is not None and agg["min_separation_min"] < CLEARANCE
    mark = "!" if close else ""
    lo, hi = agg["collision_ci95"]
    s_lo, s_hi = agg["score_ci95"]
    return [
        policy,
        str(agg["episodes"]),
        f"{agg['score_mean']:.3f} [{s_lo:.3f}, {s_hi:.3f}]",
        f"{agg['collision_rate']:.3f} [{lo:.3f}, {hi:.3f}]",
        f"{agg['pedestrian_at_fault_collision_rate']:.3f}",
        f"{agg['vehicle_at_fault_collision_rate']:.3f}",
        f"{fmt(agg['min_separation_min'])}{mark}/{fmt(agg['min_separation_p50'])}",
        f"{fmt(agg['min_ttc_p5'])}/{fmt(agg['min_ttc_p50'])}{mark}",
        fmt(agg["pet_pedestrian_first_p5"]),
        fmt(agg["drac_conflict_rate"]),
        fmt(agg["drac_crossing_p95"]),
        fmt(agg["hard_brakes_per_episode"]),
        f"{fmt(agg['yield_compliance'], 3)} ({agg['yield_obligations']})",
        str(agg["yield_unresolved"]),
        fmt(agg["max_speed_over_limit_max"]),
        fmt(agg["time_over_speed_limit_mean"]),
        fmt(agg["pass_rate"]),
        fmt(agg["censored_mean_delay"]),
    ]


def assert_same(recomputed: dict[str, Any], reported: dict[str, Any], where: str) -> None:
    assert set(recomputed) == set(reported), where
    for key, want in recomputed.items():
        got = reported[key]
        if want is None:
            assert got is None, f"{where}.{key}: {got} reported, undefined recomputed"
        else:
            assert got == pytest.approx(want, rel=1e-12, abs=1e-12), f"{where}.{key}"


def groups(doc: dict[str, Any]) -> tuple[dict[str, list[Episode]], dict[str, list[Episode]]]:
    by_policy: dict[str, list[Episode]] = {}
    by_pair: dict[str, list[Episode]] = {}
    for ep in doc["episodes"]:
        by_policy.setdefault(ep["policy"], []).append(ep)
        by_pair.setdefault(f"{ep['scenario']}/{ep['policy']}", []).append(ep)
    return by_policy, by_pair


def test_every_aggregate_recomputes_from_the_episode_records(doc: dict[str, Any]) -> None:
    durations = doc["settings"]["provenance"]["scenario_durations"]
    by_policy, by_pair = groups(doc)
    assert sorted(by_policy) == sorted(doc["settings"]["policies"])
    assert sorted(by_pair) == sorted(doc["summary"]["per_scenario_policy"]) and len(by_pair) == 6
    for policy, eps in by_policy.items():
        assert_same(recompute(eps, durations), doc["summary"]["per_policy"][policy], policy)
    for key, eps in by_pair.items():
        assert_same(recompute(eps, durations), doc["summary"]["per_scenario_policy"][key], key)


def _table_rows(text: str) -> list[list[str]]:
    lines = text.splitlines()
    assert set(lines[1]) <= {"-", " "}
    return [re.split(r" {2,}", line.strip()) for line in lines[2:] if not line.startswith(("'", "world"))]


def _markdown_tables(text: str) -> dict[str, list[list[str]]]:
    """Rows of each `report.md` table under its `##` heading (header and rule left out)."""
    tables: dict[str, list[list[str]]] = {}
    heading = ""
    for line in text.splitlines():
        if line.startswith("## "):
            heading = line[3:]
        elif line.startswith("| ") and heading:
            tables.setdefault(heading, []).append(line[2:-2].split(" | "))
    return {h: rows[1:] for h, rows in tables.items()}


def test_every_table_cell_recomputes_from_the_episode_records(run: Path, doc: dict[str, Any]) -> None:
    durations = doc["settings"]["provenance"]["scenario_durations"]
    policies = doc["settings"]["policies"]
    by_policy, by_pair = groups(doc)

    def rows(aggs: dict[str, dict[str, Any]]) -> list[list[str]]:
        """The rows, best mean score first (ties in `settings.policies` order)."""
        return [row(p, aggs[p]) for p in sorted(policies, key=lambda p: -aggs[p]["score_mean"])]

    expected = rows({p: recompute(by_policy[p], durations) for p in policies})
    assert _table_rows((run / "table_full.txt").read_text()) == expected
    tables = _markdown_tables((run / "report.md").read_text())
    assert tables["Per policy, all scenarios of the run"] == expected
    names = doc["settings"]["scenario_names"]
    for scenario in doc["settings"]["scenarios"]:
        want = rows({p: recompute(by_pair[f"{scenario}/{p}"], durations) for p in policies})
        assert tables[names[scenario]] == want, scenario


def test_every_score_recomputes_from_the_metrics_and_the_reference_on_its_seed(doc: dict[str, Any]) -> None:
    # Neither policy of the run is the reference driver: every seed's reference was added to the run.
    refs = {(e["scenario"], e["seed"]): e["metrics"] for e in doc["reference_episodes"]}
    assert {e["policy"] for e in doc["reference_episodes"]} == {"yielding"}
    assert set(refs) == {(e["scenario"], e["seed"]) for e in doc["episodes"]}
    for e in doc["episodes"]:
        want = score_of(e["metrics"], refs[(e["scenario"], e["seed"])])
        assert e["score"]["score"] == pytest.approx(want, rel=1e-12, abs=1e-12), (e["scenario"], e["policy"])
        assert all(0.0 <= v <= 1.0 for v in e["score"].values())


def test_the_world_health_line_recomputes(run: Path, doc: dict[str, Any]) -> None:
    eps = doc["episodes"]
    agg = recompute(eps, doc["settings"]["provenance"]["scenario_durations"])
    keys = [k for k in agg if k == "episodes" or k.startswith("background_")]
    assert_same({k: agg[k] for k in keys}, doc["summary"]["world_health"], "world_health")
    lo, hi = agg["background_collision_ci95"]
    line = (
        f"world health: {agg['background_collisions']} background car-pedestrian contact(s)"
        f" ({agg['background_collisions_legal']} with a legal pedestrian) in {len(eps)} episodes;"
        f" episodes with one {agg['background_collision_rate']:.3f} [{lo:.3f}, {hi:.3f}];"
        f" max relative speed {fmt(agg['background_collision_max_speed'])} m/s"
    )
    assert (run / "table_full.txt").read_text().splitlines()[-1] == line


def test_the_run_holds_the_cases_the_rules_are_about(doc: dict[str, Any]) -> None:
    """Collisions censored at the duration (not their length), time-limit cuts, rear clear but not passed."""
    durations = doc["settings"]["provenance"]["scenario_durations"]
    eps = doc["episodes"]
    for ep in eps:  # delay is set exactly when the ego passed
        assert (ep["metrics"]["delay"] is not None) == ep["metrics"]["passed_crossing"]
    crashed = [e for e in eps if e["metrics"]["collision"] and not e["metrics"]["passed_crossing"]]
    assert any(e["metrics"]["duration"] < durations[e["scenario"]] - 1.0 for e in crashed)
    cut = [e for e in eps if not e["metrics"]["collision"] and not e["metrics"]["passed_crossing"]]
    assert cut and all(e["metrics"]["duration"] == pytest.approx(durations[e["scenario"]]) for e in cut)
    rear_only = [
        e for e in eps if e["metrics"]["time_to_pass"] is not None and not e["metrics"]["passed_crossing"]
    ]
    assert rear_only, "no episode whose rear cleared the crossing without reaching the delay target"
    # Censoring a collision at the episode's length instead would change the reported delay.
    policy = crashed[0]["policy"]
    mine = [e for e in eps if e["policy"] == policy]
    at_length = np.mean(
        [censored(e, durations) if e not in crashed else e["metrics"]["duration"] for e in mine]
    )
    reported = doc["summary"]["per_policy"][policy]["censored_mean_delay"]
    assert reported == pytest.approx(np.mean([censored(e, durations) for e in mine]))
    assert at_length < reported - 0.5
