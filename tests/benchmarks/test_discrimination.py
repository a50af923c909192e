"""The discrimination report reads pedestrian risk from pedestrian collisions and violations only."""

from __future__ import annotations

from benchmarks.discrimination import cell, check_targets, render_body
from crossing_eval.runners import run_tasks
from crossing_eval.tasks import EpisodeRecord, make_tasks


def _records(scenario: str, policy: str, n: int, base: int) -> list[EpisodeRecord]:
    """Episodes through `crossing-eval`'s own tasks and runner, as the report runs them."""
    return run_tasks(make_tasks([scenario], [policy], n, base), 1, show_progress=False)


def test_rear_end_crashes_are_not_pedestrian_risk() -> None:
    """busy_zebra's careless car: its crashes are at-fault vehicle collisions, none with a pedestrian."""
    c = cell(_records("busy_zebra", "constant_speed", 8, 9000), 60.0)
    assert c["collision_rate"] > 0.0
    assert c["pedestrian_collision_rate"] == 0.0
    assert c["vehicle_collision_rate"] == c["vehicle_at_fault_collision_rate"] == c["collision_rate"]
    assert c["pedestrian_risk_rate"] == c["violation_rate"] < 1.0


def test_pedestrian_hits_are_pedestrian_risk_and_targets_read_them() -> None:
    careless = cell(_records("ncap_cpfa", "constant_speed", 4, 9000), 20.0)
    assert careless["pedestrian_collision_rate"] == careless["pedestrian_risk_rate"] == 1.0
    careful = cell(_records("ncap_cpfa", "yielding", 4, 9000), 20.0)
    cautious = dict(careful, censored_time_to_pass=careful["censored_time_to_pass"] + 1.0)
    data = {
        "seeds": 4,
        "scenarios": {
            "ncap_cpfa": {"constant_speed": careless, "yielding": careful, "always_cautious": cautious}
        },
    }
    assert not [m for m in check_targets(data) if "constant_speed" in m]
    # A careless car whose only failures are crashes into vehicles misses the pedestrian-risk target.
    rear_ender = dict(careless, pedestrian_collision_rate=0.0, violation_rate=0.0, pedestrian_risk_rate=0.0)
    data["scenarios"]["ncap_cpfa"]["constant_speed"] = rear_ender
    assert any("constant_speed hits a pedestrian or fails to yield in 0%" in m for m in check_targets(data))
    page = render_body(
        {**data, "commit": "x", "command": "c", "base_seed": 9000, "wall_seconds": 1.0, "workers": 1}
    )
    assert "| ped. collision | violation | ped. risk | veh. collision (at fault) |" in page
    assert "not pedestrian risk" in page and "ncap_cpfa / constant_speed" not in page  # it hit no vehicle
    crashed = dict(rear_ender, vehicle_collision_rate=0.5, vehicle_at_fault_collision_rate=0.5)
    data["scenarios"]["ncap_cpfa"]["constant_speed"] = crashed
    page = render_body(
        {**data, "commit": "x", "command": "c", "base_seed": 9000, "wall_seconds": 1.0, "workers": 1}
    )
    assert "ncap_cpfa / constant_speed: 0.50 of episodes (0.50 at fault)" in page
