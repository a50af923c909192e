"""NCAP-style scoring (issue 22 item 3): avoidance and impact speed per car-speed bin of ncap_* scenarios."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from agents.policy import FunctionPolicy
from crossing_env.conflict import RELEASE_DISTANCE
from crossing_eval.ncap import POINTS, colour, format_ncap_table, ncap_markdown, ncap_rows, neuro_ncap
from crossing_eval.tasks import EpisodeRecord, EpisodeTask, episode_seed, run_episode
from rollout.build import RolloutSpec, build
from rollout.episode import run_episode as run_rollout
from scenarios import load_scenario


def _record(
    scenario: str, policy: str, speed_ms: float, impact_ms: float | None, outcome: str = ""
) -> EpisodeRecord:
    result = {
        "pedestrian_collisions": int(impact_ms is not None),
        "max_impact_speed": impact_ms,
        "ncap_outcome": outcome or ("impact" if impact_ms is not None else "avoided"),
    }
    return EpisodeRecord(EpisodeTask(scenario, policy, 0, 0), result, [], [], initial_speed=speed_ms)


def test_test_speeds_outcomes_avoidance_of_the_tested_and_impact_speed() -> None:
    records = [
        _record("ncap_cpna", "constant_speed", 30 / 3.6, 24 / 3.6),
        _record("ncap_cpna", "constant_speed", 30 / 3.6, 28 / 3.6),
        _record("ncap_cpna", "constant_speed", 60 / 3.6, None),
        _record("ncap_cpna", "yielding", 60 / 3.6, None),
        _record("ncap_cpna", "yielding", 60 / 3.6, None, "outrun"),
        _record("ncap_cpna", "yielding", 60 / 3.6, None, "not tested"),
        _record("zebra_case1", "yielding", 40 / 3.6, 10.0),  # not an NCAP scenario: left out
    ]
    rows = ncap_rows(records)
    assert [(r.scenario, r.policy, r.test_kmh, r.episodes) for r in rows] == [
        ("ncap_cpna", "constant_speed", 30, 2),
        ("ncap_cpna", "constant_speed", 60, 1),
        ("ncap_cpna", "yielding", 60, 3),
    ]
    assert rows[0].avoidance == 0.0 and rows[0].impact_kmh == pytest.approx(26.0)
    assert rows[0].colours["red"] == 2 and rows[0].points == 0.0  # 24 and 28 km/h at 30 km/h: red
    assert rows[1].avoidance == 1.0 and math.isnan(rows[1].impact_kmh) and rows[1].neuro_ncap == 5.0
    # Outrunning is not avoiding, and an untested episode counts for nothing: 1 avoided of 2 tested.
    assert rows[2].counts == {"avoided": 1, "outrun": 1, "impact": 0, "not tested": 1}
    assert rows[2].tested == 2 and rows[2].avoidance == 0.5
    assert rows[2].colours == {"green": 1, "yellow": 0, "orange": 0, "brown": 0, "red": 1}
    assert rows[2].points == 0.5 and rows[2].neuro_ncap == 2.5
    page = ncap_markdown(records)
    assert "| ncap_cpna | constant_speed | 30 | 2 | 0 | 0 | 2 | 0 | 0.00 | 0/0/0/0/2 | 0.00 |" in page
    assert "| ncap_cpna | yielding | 60 | 3 | 1 | 1 | 0 | 1 | 0.50 | 1/0/0/0/1 | 0.50 | 2.50 | - |" in page
    assert ncap_markdown(records[-1:]) == ""
    # Only untested episodes: no avoidance rate, colour or score at all, never a green.
    (alone,) = ncap_rows([_record("ncap_cpfa", "stand", 40 / 3.6, None, "not tested")])
    assert math.isnan(alone.avoidance) and math.isnan(alone.points) and sum(alone.colours.values()) == 0


@pytest.mark.parametrize(
    ("test_kmh", "impact_kmh", "expected"),
    [
        # 10-20 km/h: only full avoidance counts
        (10, None, "green"),
        (10, 1.0, "red"),
        (20, 5.0, "red"),
        # 30 km/h: green 0 / brown <= 10 / red
        (30, None, "green"),
        (30, 10.0, "brown"),
        (30, 10.5, "red"),
        # 40 km/h: green 0 / orange <= 10 / brown <= 20 / red
        (40, 9.9, "orange"),
        (40, 10.1, "brown"),
        (40, 20.0, "brown"),
        (40, 20.1, "red"),
        # >= 50 km/h: green 0 / yellow <= 10 / orange <= 20 / brown <= 30 / red
        (50, 3.0, "yellow"),
        (50, 10.0, "yellow"),
        (60, 11.9, "orange"),  # the 2 km/h tolerance checks a carmaker's prediction, not the measured colour
        (60, 20.0, "orange"),
        (60, 25.0, "brown"),
        (60, 30.0, "brown"),
        (60, 30.1, "red"),
    ],
)
def test_euro_ncap_2026_colour_bands(test_kmh: int, impact_kmh: float | None, expected: str) -> None:
    outcome = "avoided" if impact_kmh is None else "impact"
    assert colour(test_kmh, outcome, math.nan if impact_kmh is None else impact_kmh) == expected


def test_colours_of_outrun_and_untested_and_the_neuro_ncap_score() -> None:
    assert colour(50, "outrun", math.nan) == "red" and colour(50, "not tested", math.nan) is None
    assert POINTS == {"green": 1.0, "yellow": 0.75, "orange": 0.5, "brown": 0.25, "red": 0.0}
    assert neuro_ncap(50, "avoided", math.nan) == 5.0
    assert neuro_ncap(50, "impact", 20.0) == pytest.approx(4 * (1 - 20 / 50))
    assert neuro_ncap(50, "impact", 50.0) == 0.0 and neuro_ncap(50, "outrun", math.nan) == 0.0
    assert math.isnan(neuro_ncap(50, "not tested", math.nan))


def _outcomes(scenario: str, action: float | None, policy: str = "constant_speed", n: int = 6) -> list[str]:
    """Outcomes of `n` episodes (base 9000) of `policy`, or of a constant action when `action` is given."""
    run = build(RolloutSpec(scenario=scenario, policy=policy))
    chosen = FunctionPolicy(lambda obs: np.full(1, action, np.float32)) if action is not None else run.policy
    try:
        return [
            run_rollout(run.env, episode_seed(9000, scenario, k), policy=chosen).result["ncap_outcome"]
            for k in range(n)
        ]
    finally:
        run.env.close()


@pytest.mark.parametrize("scenario", ["ncap_cpna", "ncap_cpfa", "ncap_cpnc", "ncap_cpla"])
def test_episode_outcomes_of_careless_careful_and_absent_cars(scenario: str) -> None:
    assert set(_outcomes(scenario, None)) == {"impact"}  # holds its speed: hits the dummy
    assert set(_outcomes(scenario, None, policy="yielding")) == {"avoided"}
    assert "not tested" in _outcomes(scenario, -1.0, n=3)  # brakes to a stand at once, far back
    assert "avoided" not in _outcomes(scenario, 1.0)  # full throttle never avoids


def test_full_throttle_that_gets_past_the_dummy_is_outrun_not_avoided() -> None:
    # ncap_cpfa, base 9000, episode 12: full throttle passes 0.14 m from the dummy (found over 20 episodes).
    run = build(RolloutSpec(scenario="ncap_cpfa", policy="constant_speed"))
    full = FunctionPolicy(lambda obs: np.ones(1, np.float32))
    result = run_rollout(run.env, episode_seed(9000, "ncap_cpfa", 12), policy=full).result
    run.env.close()
    assert result["pedestrian_collisions"] == 0 and result["min_separation"] < 0.5
    assert result["ncap_outcome"] == "outrun"
    assert _counted_as_not_avoided(result)


def _counted_as_not_avoided(result: dict) -> bool:
    (row,) = ncap_rows(
        [EpisodeRecord(EpisodeTask("ncap_cpfa", "full", 0, 0), result, [], [], initial_speed=9.5)]
    )
    return row.avoidance == 0.0 and row.counts["outrun"] == 1


def test_non_dummy_scenarios_have_no_ncap_outcome() -> None:
    assert _outcomes("midblock_jaywalker", None, n=1) == [""]
    assert _outcomes("zebra_case1", None, n=1) == [""]


def test_records_carry_the_drawn_test_speed() -> None:
    grid = set(load_scenario("ncap_cpna").conflict.ego_speed_grid)
    assert {round(v * 3.6) for v in grid} == {10, 20, 30, 40, 50, 60}  # Euro NCAP's test speeds
    tasks = [EpisodeTask("ncap_cpna", "constant_speed", e, 100 + e) for e in range(6)]
    speeds = {run_episode(t).initial_speed for t in tasks}
    assert speeds <= grid and len(speeds) >= 3  # one grid speed drawn per seed


@pytest.mark.parametrize("scenario", ["ncap_cpna", "ncap_cpfa", "ncap_cpnc", "ncap_cpla"])
def test_a_car_that_stands_far_back_is_not_tested_and_never_avoids(scenario: str) -> None:
    """Braking to a stand at once: more than 60 m from the dummy's path it is never released (not tested);
    closer, a car that stands for a second gives the dummy the way (the conflict's release rule)."""
    run = build(RolloutSpec(scenario=scenario, policy="constant_speed"))
    brake = FunctionPolicy(lambda obs: -np.ones(1, np.float32))
    for k in range(4):
        result = run_rollout(run.env, episode_seed(9000, scenario, k), policy=brake).result
        world = run.env.unwrapped.world
        front = float(world.traffic.x[0] + world.traffic.length[0] / 2)
        far = world.conflict.plan.x - world.conflict.plan.radius - front > RELEASE_DISTANCE
        assert (result["ncap_outcome"] == "not tested") == far
        assert result["ncap_outcome"] in {"not tested", "avoided"}
    run.env.close()


NCAP_SCENARIOS = ("ncap_cpna", "ncap_cpfa", "ncap_cpnc", "ncap_cpla")


@pytest.mark.parametrize("scenario", NCAP_SCENARIOS)
def test_yielding_is_green_and_holding_speed_red_at_every_test_speed(scenario: str) -> None:
    """Stopping is physically possible at every test speed of the grid once the dummy gives itself away
    (docs/evaluation.md derives each scenario's limit: 77 km/h or more), so a careful car is green at each;
    one that holds its speed is red at 30 km/h and above (at 10-20 km/h only full avoidance counts, and it
    hits there too)."""
    import dataclasses

    cfg = load_scenario(scenario)
    for v in cfg.conflict.ego_speed_grid:
        fixed = dataclasses.replace(cfg, conflict=dataclasses.replace(cfg.conflict, ego_speed_grid=(v,)))
        kmh = round(v * 3.6)
        for policy, expected in (("yielding", "green"), ("constant_speed", "red")):
            run = build(RolloutSpec(scenario=fixed, policy=policy))
            try:
                for k in range(2):
                    seed = episode_seed(4242, scenario, k)
                    result = run_rollout(run.env, seed, policy=run.policy).result
                    speed = result["ncap_impact_speed"]
                    impact = math.nan if speed is None else 3.6 * speed
                    got = colour(kmh, result["ncap_outcome"], impact)
                    assert got == expected, f"{scenario} {policy} at {kmh} km/h, seed {seed}: {got}"
            finally:
                run.env.close()


def test_the_printed_table_has_a_line_per_test_speed_and_the_relative_impact_speed() -> None:
    records = [
        _record("ncap_cpla", "constant_speed", 20 / 3.6, 20 / 3.6),
        _record("ncap_cpla", "yielding", 20 / 3.6, None),
    ]
    records[0].result["ncap_impact_speed"] = 15 / 3.6  # 20 km/h less the walker's 5: the scored speed
    text = format_ncap_table(ncap_rows(records))
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["scenario", "policy", "km/h"] and set(lines[1]) <= {"-", " "}
    assert lines[2].split() == ["ncap_cpla", "constant_speed", "20", "1", "0/0/1/0", "0/0/0/0/1", "0.00",
                                "1.00", "15.0"]  # fmt: skip
    assert lines[3].split() == [
        "ncap_cpla",
        "yielding",
        "20",
        "1",
        "1/0/0/0",
        "1/0/0/0/0",
        "1.00",
        "5.00",
        "-",
    ]


def test_crossing_eval_prints_the_ncap_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from crossing_eval.cli import main

    args = ["--scenarios", "ncap_cpla,zebra_case1", "--policies", "constant_speed", "--episodes", "1"]
    assert main([*args, "--workers", "1", "--no-progress", "--out", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert "avoid/outrun/impact/untested" in out and "\nncap_cpla  constant_speed" in out
    assert "zebra_case1  constant" not in out  # only the NCAP scenarios have rows
