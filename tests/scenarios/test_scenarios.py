from __future__ import annotations

import dataclasses
import datetime as dt
import math
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import scenarios
from scenarios import (
    BUILTIN_DIR,
    ScenarioError,
    dump_scenario,
    list_scenarios,
    load_scenario,
    parse_scenario,
    save_scenario,
    scenario_from_dict,
    to_toml,
    validate_scenario,
)
from scenarios.config import ScenarioConfig, VehicleSpawn

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

REQUIRED = {
    "zebra_case1",
    "busy_zebra",
    "signalised_red_light",
    "midblock_jaywalker",
    "occluded_parked_car",
    "children_running",
    "night_distracted",
}
NAMES = sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))


def _write(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _error(path: Path | str) -> ScenarioError:
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    return info.value


# ------------------------------------------------------------------------------------------ built-ins


def test_required_builtins_present_and_listed() -> None:
    listing = list_scenarios()
    assert REQUIRED <= set(listing)
    assert set(listing) == set(NAMES)
    for name, description in listing.items():
        assert description.strip() and "\n" not in description, name
        assert description != ScenarioConfig().description, f"{name} kept the default description"


@pytest.mark.parametrize("name", NAMES)
def test_builtin_loads_and_is_realistic(name: str) -> None:
    cfg = load_scenario(name)
    assert isinstance(cfg, ScenarioConfig)
    assert cfg.name == name
    assert 200.0 <= cfg.road.length <= 260.0
    assert 30.0 <= cfg.duration <= 45.0
    assert 11.0 <= cfg.ego.speed <= 13.0
    assert cfg.ego.speed <= cfg.road.speed_limit
    # The ego meets its conflict point 80–90 m ahead: the crossing, or the mid-block crossing point.
    conflict_x = [cfg.crossing.position] + [s.crossing_x for s in cfg.pedestrians.spawns if s.crossing_x]
    assert any(80.0 <= x - cfg.ego.x <= 90.0 for x in conflict_x), (cfg.ego.x, conflict_x)
    # The same object comes back by path as by name.
    assert load_scenario(BUILTIN_DIR / f"{name}.toml") == cfg
    assert load_scenario(str(BUILTIN_DIR / f"{name}.toml")) == cfg


@pytest.mark.parametrize("name", NAMES)
def test_round_trip(name: str, tmp_path: Path) -> None:
    cfg = load_scenario(name)
    text = dump_scenario(cfg)
    assert parse_scenario(text) == cfg
    saved = save_scenario(cfg, tmp_path / "copy.toml")
    assert load_scenario(saved) == cfg
    assert list(tmp_path.iterdir()) == [saved]  # no temp file left behind


def test_zebra_case1_matches_the_seed_case() -> None:
    cfg = load_scenario("zebra_case1")
    assert cfg.crossing.kind == "zebra" and cfg.road.num_lanes == 2
    cars = [s for s in cfg.traffic.spawns if not s.parked]
    assert len(cars) == 3
    distances = sorted(abs(s.x - cfg.crossing.position) for s in cars)
    assert distances[0] < 35 < distances[1] < 60 < distances[2]  # near / mid / far
    # All three approach the crossing (backward lane, east of it).
    backward = set(range(cfg.road.num_forward_lanes, cfg.road.num_lanes))
    assert all(s.lane in backward and s.x > cfg.crossing.position for s in cars)
    waiting = [p for p in cfg.pedestrians.spawns if p.crosses]
    assert len(waiting) >= 2
    assert all(abs(p.x - cfg.crossing.position) <= cfg.crossing.width / 2 for p in waiting)


def test_situations_have_their_defining_features() -> None:
    busy = load_scenario("busy_zebra")
    groups = [p.group for p in busy.pedestrians.spawns if p.group >= 0]
    assert len(set(groups)) >= 2 and busy.pedestrians.group_probability >= 0.3
    assert busy.pedestrians.spawn_rate > ScenarioConfig().pedestrians.spawn_rate
    assert busy.traffic.offer_timeout > 0.0 and busy.pedestrians.behaviour.decision_model == "qlb"

    red = load_scenario("signalised_red_light")
    assert red.crossing.kind == "signalised"
    assert red.pedestrians.behaviour.red_light_rate > ScenarioConfig().pedestrians.behaviour.red_light_rate
    signal = red.crossing.signal
    # The ego has green (pedestrians red) when it arrives.
    t_arrive = (red.crossing.position - red.ego.x) / min(red.conflict.ego_speed)
    phase = (signal.offset + t_arrive) % (signal.pedestrian_green + signal.pedestrian_red)
    assert phase >= signal.pedestrian_green

    # The jaywalker, the red-light runner, the hidden pedestrian and the phone user are timed to the ego.
    jay = load_scenario("midblock_jaywalker")
    assert jay.crossing.kind == "none" and jay.conflict is not None and jay.conflict.side == "far"
    assert jay.ego.x < jay.crossing.position + min(jay.conflict.x_offset)
    assert red.conflict is not None

    occ = load_scenario("occluded_parked_car")
    parked = [s for s in occ.traffic.spawns if s.parked]
    assert parked and all(s.speed == 0.0 for s in parked)
    nearest = max(parked, key=lambda s: s.x)
    assert occ.ego.x < nearest.x < occ.crossing.position
    assert occ.crossing.position - nearest.x < 15.0
    hidden = occ.conflict
    # The pedestrian stands right in front of the van (moved per seed), on its kerb side, on the zebra.
    assert hidden is not None and hidden.side == "near" and 0.0 < min(hidden.occluder_gap) < 2.0
    lo = occ.crossing.position + min(hidden.x_offset)
    assert occ.crossing.position - occ.crossing.width / 2 < lo

    kids = load_scenario("children_running")
    children = [p for p in kids.pedestrians.spawns if p.radius is not None and p.radius <= 0.22]
    assert len(children) >= 2
    assert all(p.runs and p.critical_gap is not None and p.critical_gap < 3.0 for p in children)

    night = load_scenario("night_distracted")
    assert night.night
    assert night.conflict is not None and night.conflict.distracted and night.conflict.side == "either"
    assert max(night.conflict.pedestrian_speed) < 1.6


def test_name_defaults_to_file_stem(tmp_path: Path) -> None:
    path = _write(tmp_path, "duration = 33.0\n", "my_street.toml")
    cfg = load_scenario(path)
    assert cfg.name == "my_street" and cfg.duration == 33.0
    assert cfg.road == ScenarioConfig().road  # everything else keeps the dataclass defaults


# ---------------------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("text", "field", "value", "allowed"),
    [
        # unknown keys, with a suggestion
        (
            "[pedestrians.behaviour]\nrunning_rat = 0.1\n",
            "pedestrians.behaviour.running_rat",
            "0.1",
            "running_rate",
        ),
        ("colour = 'red'\n", "colour", "'red'", "allowed keys"),
        (
            "[[traffic.spawns]]\nlane = 0\nx = 50.0\nspeed = 3.0\nbrand = 'x'\n",
            "traffic.spawns[0].brand",
            "'x'",
            "unknown",
        ),
        # wrong types: no coercion
        ('[road]\nnum_lanes = "2"\n', "road.num_lanes", "'2'", "integer"),
        ("[road]\nnum_lanes = 2.0\n", "road.num_lanes", "2.0", "integer"),
        ("[road]\ntwo_way = 1\n", "road.two_way", "1", "true or false"),
        ("[ego]\nspeed = true\n", "ego.speed", "True", "number"),
        ("[crossing]\nkind = 'pelican'\n", "crossing.kind", "'pelican'", "'zebra', 'signalised', 'none'"),
        ("road = 3\n", "road", "3", "table"),
        ("[traffic]\nspawns = 3\n", "traffic.spawns", "3", "array of tables"),
        ("[ego]\nspeed = nan\n", "ego.speed", "nan", "finite"),
        ("[ego]\nspeed = 1979-05-27\n", "ego.speed", "datetime.date(1979, 5, 27)", "number"),
        (
            "[[traffic.spawns]]\nlane = 0\nx = 50.0\n",
            "traffic.spawns[0].speed",
            "",
            "required key is missing",
        ),
        # out of range
        (
            "[pedestrians.behaviour]\nrunning_rate = 1.5\n",
            "pedestrians.behaviour.running_rate",
            "1.5",
            "[0, 1]",
        ),
        ("[traffic]\nyield_probability = -0.1\n", "traffic.yield_probability", "-0.1", "[0, 1]"),
        ("[road]\nnum_lanes = 5\n", "road.num_lanes", "5", "[1, 4]"),
        ("[road]\nlane_width = 0.0\n", "road.lane_width", "0.0", "[2.5, 5] m"),
        ("duration = 0.0\n", "duration", "0.0", "[2, 3600] s"),
        ("[pedestrians]\nmax_pedestrians = 0\n", "pedestrians.max_pedestrians", "0", "[1, 500]"),
        (
            "[crossing.signal]\npedestrian_green = 0.0\n",
            "crossing.signal.pedestrian_green",
            "0.0",
            "[4, 240] s",
        ),
        ("[ego]\nspeed = -1.0\n", "ego.speed", "-1.0", "[0, 40] m/s"),
        ("[[pedestrians.spawns]]\nx = 100.0\nphase = 4.0\n", "pedestrians.spawns[0].phase", "4.0", "π"),
        # values that are wrong only for this road
        ("[[traffic.spawns]]\nlane = 2\nx = 50.0\nspeed = 3.0\n", "traffic.spawns[0].lane", "2", "0..1"),
        ("[ego]\nlane = 1\n", "ego.lane", "1", "forward lane: 0..0"),
        ("[crossing]\nposition = 500.0\n", "crossing.position", "500.0", "[2, 238]"),
        ("[[pedestrians.spawns]]\nx = -5.0\n", "pedestrians.spawns[0].x", "-5.0", "[0, 240]"),
        ("[crossing.signal]\noffset = 40.0\n", "crossing.signal.offset", "40.0", "< the cycle length 37"),
        (
            "[pedestrians]\ndesired_speed_mean = 2.5\n",
            "pedestrians.desired_speed_mean",
            "2.5",
            "[desired_speed_min, desired_speed_max]",
        ),
        (
            "[[traffic.spawns]]\nlane = 0\nx = 32.0\nspeed = 5.0\n",
            "traffic.spawns[0].x",
            "32.0",
            "overlaps ego",
        ),
        (
            "[conflict]\nside = 'ahead'\n",
            "conflict.dummy",
            "False",
            "must be true when conflict.side is 'ahead'",
        ),
        (
            "[[traffic.spawns]]\nlane = 0\nx = 99.0\nspeed = 5.0\nparked = true\n",
            "traffic.spawns[0].speed",
            "5.0",
            "parked",
        ),
    ],
)
def test_bad_file_names_file_field_value_and_rule(
    tmp_path: Path, text: str, field: str, value: str, allowed: str
) -> None:
    path = _write(tmp_path, text)
    err = _error(path)
    message = str(err)
    assert isinstance(err, ValueError)
    assert str(path) in message
    assert field in message
    assert value in message
    assert allowed in message
    assert any(p.field == field for p in err.problems)


def test_all_problems_reported_together(tmp_path: Path) -> None:
    path = _write(tmp_path, "[road]\nnum_lanes = 'two'\nlane_width = true\n[ego]\nbogus = 1\n")
    err = _error(path)
    assert {p.field for p in err.problems} == {"road.num_lanes", "road.lane_width", "ego.bogus"}
    assert "3 problems" in str(err)


def test_toml_syntax_error_names_file_and_line(tmp_path: Path) -> None:
    path = _write(tmp_path, 'name = "x"\n[road]\nnum_lanes = = 2\n')
    message = str(_error(path))
    assert str(path) in message and "line 3" in message and "invalid TOML" in message


def test_duplicate_key_is_a_syntax_error(tmp_path: Path) -> None:
    message = str(_error(_write(tmp_path, "duration = 30.0\nduration = 31.0\n")))
    assert "invalid TOML" in message and "line 2" in message


def test_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes('description = "café"\n'.encode("latin-1"))
    message = str(_error(path))
    assert str(path) in message and "UTF-8" in message


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.toml"
    message = str(_error(path))
    assert str(path) in message and "not found" in message


def test_unknown_name_lists_available() -> None:
    message = str(_error("zebra_case2"))
    assert "unknown scenario 'zebra_case2'" in message
    assert "did you mean 'zebra_case1'" in message
    for name in NAMES:
        assert name in message


def test_validate_scenario_checks_python_made_configs(tmp_path: Path) -> None:
    cfg = load_scenario("zebra_case1")
    assert validate_scenario(cfg) == cfg
    bad = dataclasses.replace(
        cfg, traffic=dataclasses.replace(cfg.traffic, spawns=(VehicleSpawn(lane=3, x=10.0, speed=1.0),))
    )
    with pytest.raises(ScenarioError, match=r"<config>: traffic\.spawns\[0\]\.lane = 3"):
        validate_scenario(bad)
    # Saving an invalid config writes nothing and leaves an existing file untouched.
    target = tmp_path / "kept.toml"
    target.write_text("duration = 31.0\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match=str(target)):
        save_scenario(bad, target)
    assert target.read_text(encoding="utf-8") == "duration = 31.0\n"
    assert list(tmp_path.iterdir()) == [target]


# ------------------------------------------------------------------------------------------- fuzzing

_scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.dates(),
    st.times(),
    st.datetimes(),
    st.datetimes(timezones=st.just(dt.timezone.utc)),
)
_values = st.recursive(
    _scalars,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=6,
)
# 1.5x the profile's budget (tests/conftest.py): 150 examples under `ci`, derandomized.
_FUZZ = settings(
    max_examples=3 * settings().max_examples // 2, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def _locations(node: Any, out: list[tuple[Any, Any]]) -> list[tuple[Any, Any]]:
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for key, value in items:
        out.append((node, key))
        if isinstance(value, (dict, list)):
            _locations(value, out)
    return out


def _check_outcome(text: str) -> None:
    try:
        cfg = parse_scenario(text, "<fuzz>")
    except ScenarioError as err:
        assert str(err).startswith("<fuzz>")
        assert err.problems
    else:
        assert isinstance(cfg, ScenarioConfig)
        assert validate_scenario(cfg) == cfg  # anything accepted is valid by the same rules


@_FUZZ
@given(st.text(max_size=200))
def test_fuzz_arbitrary_text(text: str) -> None:
    _check_outcome(text)


@_FUZZ
@given(data=st.data())
def test_fuzz_mutated_scenarios(data: st.DataObject) -> None:
    doc = tomllib.loads(dump_scenario(load_scenario(data.draw(st.sampled_from(NAMES)))))
    for _ in range(data.draw(st.integers(1, 3))):
        container, key = data.draw(st.sampled_from(_locations(doc, [])))
        action = data.draw(st.sampled_from(["number", "replace", "delete", "add"]))
        old = container[key]
        if action == "number" and isinstance(old, float):
            # Same type, any magnitude: exercises the value ranges and the cross-field checks.
            container[key] = data.draw(st.floats(-1e3, 1e3) | st.sampled_from([0.0, -0.0, 1e300, 5e-324]))
        elif action == "number" and isinstance(old, int) and not isinstance(old, bool):
            container[key] = data.draw(st.integers(-3, 40) | st.integers(-(2**64), 2**64))
        elif action in ("number", "replace"):
            container[key] = data.draw(_values)
        elif action == "delete":
            del container[key]
        elif isinstance(container, dict):
            container[data.draw(st.text(min_size=1, max_size=8))] = data.draw(_values)
    _check_outcome(to_toml(doc))
    # Feeding the data directly gives the same verdict as the TOML text.
    try:
        scenario_from_dict(doc, "<fuzz>")
    except ScenarioError as err:
        assert str(err).startswith("<fuzz>")


@_FUZZ
@given(data=st.data())
def test_fuzz_text_edits_of_a_valid_file(data: st.DataObject) -> None:
    text = (BUILTIN_DIR / f"{data.draw(st.sampled_from(NAMES))}.toml").read_text(encoding="utf-8")
    for _ in range(data.draw(st.integers(1, 4))):
        at = data.draw(st.integers(0, len(text)))
        cut = data.draw(st.integers(0, 5))
        text = text[:at] + data.draw(st.text(max_size=4)) + text[at + cut :]
    _check_outcome(text)


@_FUZZ
@given(st.dictionaries(st.text(max_size=6), _values, max_size=4))
def test_to_toml_round_trips_through_tomllib(doc: dict[str, Any]) -> None:
    def no_nan(node: Any) -> bool:
        if isinstance(node, float):
            return not math.isnan(node)
        if isinstance(node, dict):
            return all(no_nan(v) for v in node.values())
        if isinstance(node, list):
            return all(no_nan(v) for v in node)
        return True

    text = to_toml(doc)
    loaded = tomllib.loads(text)
    if no_nan(doc):
        assert loaded == doc


def test_to_toml_regression_key_with_trailing_newline() -> None:
    """Once drawn by the fuzzer: the old hand-written emitter wrote the key '0\\n' bare, as invalid TOML."""
    doc = {"0\n": {}}
    assert tomllib.loads(to_toml(doc)) == doc


@pytest.mark.parametrize("name", ["abc\n", "abc\r", "a\tb", "\x00", "zebra\x7f"])
def test_names_reject_control_characters(name: str) -> None:
    with pytest.raises(ScenarioError, match="name"):
        validate_scenario(ScenarioConfig(name=name))


@pytest.mark.parametrize("description", ["two\nlines", "tab\there", "bell\x07"])
def test_descriptions_reject_control_characters(description: str) -> None:
    with pytest.raises(ScenarioError, match="description"):
        validate_scenario(ScenarioConfig(description=description))


def test_keys_with_control_characters_are_unknown_keys() -> None:
    with pytest.raises(ScenarioError, match="unknown key"):
        parse_scenario('name = "x"\n"duration\\n" = 3.0\n')


def test_empty_file_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "empty.toml"
    path.write_text("", encoding="utf-8")
    with pytest.raises(ScenarioError, match="empty scenario"):
        load_scenario(path)


def test_scenario_error_pickles_whole() -> None:
    import pickle

    with pytest.raises(ScenarioError) as caught:
        parse_scenario("name = 3", "bad.toml")
    err = caught.value
    back = pickle.loads(pickle.dumps(err))
    assert isinstance(back, ScenarioError)
    assert str(back) == str(err) and back.source == "bad.toml" and back.problems == err.problems


def test_public_api_exports() -> None:
    assert scenarios.BUILTIN_DIR.is_dir()
    assert issubclass(scenarios.ScenarioError, ValueError)
