"""Physically implausible scenarios are refused (issue 25, item 9).

Every file below was accepted by the earlier ranges (a 24 m car, a 0.9 m-radius person, 0.01 m/s² of
braking, a 0.05 s episode, 5,000 pedestrians, a 9 km road, a 20 cm sidewalk, a 5.5 m/s walk); each is now
an error naming the file, the field's dotted name and the value, with the allowed range and its reason.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

from scenarios import BUILTIN_DIR, ScenarioError, load_scenario
from scenarios.config import ScenarioConfig
from scenarios.validation import VALUE_RULES

REPO = Path(__file__).resolve().parents[2]

IMPLAUSIBLE = [
    # (case, TOML text, field, value as printed, text of the allowed range)
    ("car_too_long", "[traffic]\nlength = 24.0\n", "traffic.length", "24.0", "[2, 20] m"),
    ("car_too_wide", "[traffic]\nwidth = 2.9\n", "traffic.width", "2.9", "[1.2, 2.6] m"),
    ("car_too_small", "[traffic]\nlength = 0.5\n", "traffic.length", "0.5", "[2, 20] m"),
    ("person_too_big", "[pedestrians]\nradius = 0.9\n", "pedestrians.radius", "0.9", "[0.15, 0.5] m"),
    (
        "spawned_person_too_big",
        "[[pedestrians.spawns]]\nx = 100.0\nradius = 0.8\n",
        "pedestrians.spawns[0].radius",
        "0.8",
        "[0.15, 0.5] m",
    ),
    ("person_too_small", "[pedestrians]\nradius = 0.02\n", "pedestrians.radius", "0.02", "[0.15, 0.5] m"),
    ("ego_braking_near_zero", "[ego]\nmax_deceleration = 0.01\n", "ego.max_deceleration", "0.01", "[1, 12]"),
    (
        "background_braking_near_zero",
        "[traffic.idm]\ncomfortable_deceleration = 0.02\nmax_deceleration = 0.05\n",
        "traffic.idm.max_deceleration",
        "0.05",
        "[1, 12] m/s²",
    ),
    (
        "ego_braking_beyond_grip",
        "[ego]\nmax_deceleration = 14.0\n",
        "ego.max_deceleration",
        "14.0",
        "[1, 12]",
    ),
    ("duration_below_one_step", "duration = 0.05\n", "duration", "0.05", "[2, 3600] s"),
    ("duration_below_ten_steps", "duration = 0.9\n", "duration", "0.9", "[2, 3600] s"),
    ("duration_below_five_coarse_steps", "duration = 1.5\n", "duration", "1.5", "[2, 3600] s"),
    (
        "pedestrian_pool_absurd",
        "[pedestrians]\nmax_pedestrians = 5000\n",
        "pedestrians.max_pedestrians",
        "5000",
        "[1, 500]",
    ),
    ("vehicle_pool_absurd", "[traffic]\nmax_vehicles = 900\n", "traffic.max_vehicles", "900", "[1, 200]"),
    ("road_absurdly_long", "[road]\nlength = 9000.0\n", "road.length", "9000.0", "[50, 2000] m"),
    (
        "road_absurdly_short",
        "[road]\nlength = 25.0\n[crossing]\nposition = 12.0\n[ego]\nx = 2.0\n",
        "road.length",
        "25.0",
        "[50, 2000] m",
    ),
    ("lane_too_wide", "[road]\nlane_width = 5.8\n", "road.lane_width", "5.8", "[2.5, 5] m"),
    ("lane_too_narrow", "[road]\nlane_width = 2.2\n", "road.lane_width", "2.2", "[2.5, 5] m"),
    ("sidewalk_too_narrow", "[road]\nsidewalk_width = 0.2\n", "road.sidewalk_width", "0.2", "[1, 12] m"),
    ("sidewalk_too_wide", "[road]\nsidewalk_width = 19.0\n", "road.sidewalk_width", "19.0", "[1, 12] m"),
    (
        "walking_speed_absurd",
        "[pedestrians]\ndesired_speed_max = 5.5\n",
        "pedestrians.desired_speed_max",
        "5.5",
        "[0.3, 3] m/s",
    ),
    (
        "spawned_walker_absurd",
        "[[pedestrians.spawns]]\nx = 100.0\ndesired_speed = 5.0\n",
        "pedestrians.spawns[0].desired_speed",
        "5.0",
        "[0.3, 3] m/s",
    ),
    (
        "walking_speed_near_zero",
        "[pedestrians]\ndesired_speed_min = 0.05\n",
        "pedestrians.desired_speed_min",
        "0.05",
        "[0.3, 3] m/s",
    ),
    ("ego_speed_absurd", "[ego]\nspeed = 50.0\nmax_speed = 55.0\n", "ego.speed", "50.0", "[0, 40] m/s"),
    ("ego_cap_absurd", "[ego]\nmax_speed = 55.0\n", "ego.max_speed", "55.0", "[2, 40] m/s"),
    (
        "car_speed_absurd",
        "[[traffic.spawns]]\nlane = 1\nx = 200.0\nspeed = 55.0\n",
        "traffic.spawns[0].speed",
        "55.0",
        "[0, 40] m/s",
    ),
    ("speed_limit_absurd", "[road]\nspeed_limit = 38.0\n", "road.speed_limit", "38.0", "[2, 27.8] m/s"),
    (
        "flow_beyond_capacity",
        "[traffic]\nflow_per_lane = 3500.0\n",
        "traffic.flow_per_lane",
        "3500.0",
        "[0, 2400]",
    ),
    (
        "arrivals_beyond_capacity",
        "[pedestrians]\nspawn_rate = 550.0\n",
        "pedestrians.spawn_rate",
        "550.0",
        "[0, 300]",
    ),
    ("crossing_too_wide", "[crossing]\nwidth = 18.0\n", "crossing.width", "18.0", "[1.8, 10] m"),
    (
        "stop_line_far",
        "[crossing]\nstop_line_offset = 45.0\n",
        "crossing.stop_line_offset",
        "45.0",
        "[0, 15] m",
    ),
    (
        "signal_green_absurd",
        "[crossing.signal]\npedestrian_green = 500.0\n",
        "crossing.signal.pedestrian_green",
        "500.0",
        "[4, 240] s",
    ),
    (
        "idm_headway_near_zero",
        "[traffic.idm]\ntime_headway = 0.01\n",
        "traffic.idm.time_headway",
        "0.01",
        "[0.5, 5] s",
    ),
    (
        "social_force_range_absurd",
        "[pedestrians.social_force]\nped_range = 8.0\n",
        "pedestrians.social_force.ped_range",
        "8.0",
        "[0.05, 2] m",
    ),
]


@pytest.mark.parametrize(
    ("text", "field", "value", "allowed"),
    [pytest.param(*case[1:], id=case[0]) for case in IMPLAUSIBLE],
)
def test_implausible_value_is_refused_naming_file_field_and_value(
    tmp_path: Path, text: str, field: str, value: str, allowed: str
) -> None:
    path = tmp_path / "implausible.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith(str(path))
    assert f"{field} = {value}: must be in {allowed}" in message
    problem = next(p for p in info.value.problems if p.field == field)
    assert "(" in problem.allowed and problem.allowed.endswith(")")  # the reason for the bounds is given


PHYSICAL = {
    "RoadConfig": ("lane_width", "length", "speed_limit", "sidewalk_width", "parking_strip"),
    "CrosswalkConfig": ("width", "stop_line_offset"),
    "SignalConfig": ("pedestrian_green", "pedestrian_red"),
    "IDMConfig": (
        "max_acceleration",
        "comfortable_deceleration",
        "max_deceleration",
        "time_headway",
        "min_gap",
    ),
    "VehicleSpawn": ("speed", "desired_speed"),
    "TrafficConfig": ("flow_per_lane", "desired_speed_std", "length", "width"),
    "EgoConfig": ("speed", "max_acceleration", "max_deceleration", "max_speed"),
    "PedestrianSpawn": ("desired_speed", "radius", "critical_gap"),
    "PedestrianConfig": (
        "spawn_rate",
        "spawn_extent",
        "desired_speed_mean",
        "desired_speed_std",
        "desired_speed_min",
        "desired_speed_max",
        "radius",
    ),
    "SocialForceConfig": ("relaxation_time", "base_strength", "ped_range", "vehicle_range", "kerb_range"),
    "ScenarioConfig": ("duration",),
}
"""Fields holding a physical quantity: each has a unit and a stated reason for its bounds."""


def test_every_physical_range_has_a_unit_and_states_its_reason() -> None:
    rules = {(cls.__name__, name): rule for (cls, name), rule in VALUE_RULES.items()}
    for owner, names in PHYSICAL.items():
        for name in names:
            rule = rules[(owner, name)]
            assert rule.unit and rule.why, f"{owner}.{name}: {rule.allowed}"
    unexplained = [key for key, rule in rules.items() if rule.unit and not rule.why]
    assert not unexplained
    # The pool caps are usability caps, and say so.
    assert "usability" in rules[("PedestrianConfig", "max_pedestrians")].why
    assert "usability" in rules[("TrafficConfig", "max_vehicles")].why


def test_defaults_and_builtins_lie_inside_the_ranges() -> None:
    for (cls, name), rule in VALUE_RULES.items():
        f = next(f for f in dataclasses.fields(cls) if f.name == name)
        if f.default is not dataclasses.MISSING and f.default is not None:
            assert rule.check(f.default), f"{cls.__name__}.{name} default {f.default!r}: {rule.allowed}"
    for path in sorted(BUILTIN_DIR.glob("*.toml")):
        load_scenario(path)  # validated against the same ranges
    assert load_scenario(BUILTIN_DIR / "zebra_case1.toml") != ScenarioConfig()


def test_crossing_eval_exits_2_on_an_implausible_scenario(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bus_of_doom"\n[traffic]\nlength = 24.0\n', encoding="utf-8")
    out = tmp_path / "out"
    argv = ["--scenarios", str(bad), "--policies", "yielding", "--episodes", "1", "--workers", "1"]
    result = subprocess.run(
        [sys.executable, "-m", "crossing_eval.cli", *argv, "--no-progress", "--out", str(out)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert str(bad) in result.stderr and "traffic.length = 24.0" in result.stderr
    assert not out.exists()
