"""Bounded-rational pedestrians: the QLB decision model, irrational acts at their rates, groups, red light."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest

from crossing_env.pedestrians.behaviour import (
    QuantumGapAcceptance,
    QuantumGapConfig,
    irrational_neighbour_fraction,
    per_step_hazard,
    safe_belief,
    updated_ped_intensity,
)
from crossing_env.pedestrians.decisions import DecisionContext, GapAcceptance
from crossing_env.pedestrians.population import CarSnapshot, PedestrianPopulation
from crossing_env.pedestrians.transitions import CROSSING, WAITING
from crossing_env.types import BehaviourEvent
from crossing_env.world import World
from scenarios.config import (
    BehaviourConfig,
    CrosswalkConfig,
    EgoConfig,
    PedestrianConfig,
    PedestrianSpawn,
    ScenarioConfig,
    SignalConfig,
    TrafficConfig,
)

HALF_PI = math.pi / 2


def _context(
    gap: np.ndarray, crit: np.ndarray, phase: np.ndarray, dt: float = 0.1, red: bool = False
) -> DecisionContext:
    n = gap.size
    return DecisionContext(
        gap=gap,
        critical_gap=crit,
        phase=phase,
        waited=np.zeros(n),
        red=np.full(n, red),
        red_violator=np.zeros(n, dtype=bool),
        dt=dt,
    )


def _run(scenario: ScenarioConfig, seconds: float, seed: int = 0) -> tuple[World, list[BehaviourEvent]]:
    """Run a world (the ego holds its speed) and return it with every behaviour event logged."""
    world = World(scenario, np.random.default_rng(seed))
    events = []
    for _ in range(round(seconds / world.dt)):
        world.step(0.0)
        events.extend(world.pedestrians.events)
    return world, events


# ------------------------------------------------------------------ the decision model
def test_qlb_identity_at_cos_zero_is_the_classical_pedestrian() -> None:
    rng = np.random.default_rng(1)
    gap = np.concatenate([rng.uniform(0, 15, 500), [np.inf, 0.0]])
    crit = rng.uniform(3, 9, gap.size)
    model = QuantumGapAcceptance()
    c = model.config
    beta = safe_belief(gap, crit, c.belief_scale)
    mixture = beta * c.p_cross_safe + (1 - beta) * c.p_cross_unsafe  # plain mixture, computed independently
    classical = np.where(gap >= np.minimum(c.gap_floor, crit), mixture, 0.0)
    quantum = model.look_probability(gap, crit, np.full(gap.size, HALF_PI))
    np.testing.assert_allclose(quantum, classical, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(model.classical_probability(gap, crit), classical, rtol=1e-13, atol=1e-15)
    # Per step: the hazard of the classical look probability.
    step = model.probability(_context(gap, crit, np.full(gap.size, HALF_PI)))
    np.testing.assert_allclose(
        step, 1 - (1 - classical) ** (0.1 / c.decision_interval), rtol=1e-12, atol=1e-15
    )
    # And interference does bend it away from cos = 0.
    bent = model.look_probability(gap, crit, np.full(gap.size, HALF_PI + 0.6))
    assert np.max(np.abs(bent - classical)) > 0.02


def test_step_limit_is_exactly_classical_gap_acceptance() -> None:
    rng = np.random.default_rng(2)
    gap = rng.uniform(0, 12, 300)
    crit = rng.uniform(3, 9, 300)
    model = QuantumGapAcceptance(QuantumGapConfig(belief_scale=0.0, p_cross_safe=1.0, p_cross_unsafe=0.0))
    for phase in (HALF_PI, 0.3, 2.8):  # no interference possible with a certain belief
        ctx = _context(gap, crit, np.full(300, phase))
        np.testing.assert_array_equal(model.probability(ctx), GapAcceptance().probability(ctx))


@pytest.mark.parametrize("offset", [0.0, 0.4, 0.8, -0.4, -0.8, -1.4])
def test_crossing_probability_rises_with_the_gap(offset: float) -> None:
    model = QuantumGapAcceptance()
    gap = np.linspace(0.0, 15.0, 1501)
    crit = np.full_like(gap, 5.5)
    p = model.look_probability(gap, crit, np.full_like(gap, HALF_PI + offset))
    # Constructive or no interference: monotonic. Destructive: a dip of at most 2e-4 at near-zero beliefs,
    # where the two "cross" amplitudes nearly cancel (documented in the module).
    tol = 0.0 if math.cos(HALF_PI + offset) >= -1e-12 else 2e-4
    assert np.all(np.diff(p) >= -tol - 1e-15)
    assert p[0] < 0.01 and p[-1] > 0.9
    assert p[np.searchsorted(gap, 7.0)] - p[np.searchsorted(gap, 4.0)] > 0.5


def test_per_step_hazard_does_not_depend_on_dt() -> None:
    model = QuantumGapAcceptance()
    gap, crit, phase = np.array([4.8, 5.5, 6.3]), np.array([5.5, 5.5, 5.5]), np.array([1.2, 1.6, 2.0])
    survival = {}
    for dt in (0.05, 0.1, 0.2):
        p = model.probability(_context(gap, crit, phase, dt=dt))
        survival[dt] = (1 - p) ** round(1.0 / dt)  # not having crossed within 1 s at a constant gap
    np.testing.assert_allclose(survival[0.05], survival[0.2], rtol=1e-9)
    np.testing.assert_allclose(survival[0.1], survival[0.2], rtol=1e-9)
    assert per_step_hazard(np.array([1.0]), 0.1, 0.5)[0] == 1.0
    with pytest.raises(ValueError, match="dt"):
        per_step_hazard(np.array([0.5]), 0.0, 0.5)


def test_red_light_blocks_non_violators_in_the_qlb_model() -> None:
    n = 4
    ctx = DecisionContext(
        gap=np.full(n, np.inf),
        critical_gap=np.full(n, 5.0),
        phase=np.full(n, 2.0),
        waited=np.zeros(n),
        red=np.array([True, True, False, False]),
        red_violator=np.array([False, True, False, True]),
        dt=0.1,
    )
    p = QuantumGapAcceptance().probability(ctx)
    assert p[0] == 0.0 and np.all(p[1:] > 0.2)


def test_bad_config_names_the_field() -> None:
    with pytest.raises(ValueError, match="p_cross_safe"):
        QuantumGapConfig(p_cross_safe=1.5)
    with pytest.raises(ValueError, match="decision_interval"):
        QuantumGapConfig(decision_interval=0.0)


def _accepted_gaps(model: object, n: int, headway: float, seed: int, dt: float = 0.1) -> np.ndarray:
    """Gap accepted by each of n pedestrians waiting at a kerb with Poisson traffic (mean headway, s).

    Isolates the decision model from the rest of the world: each pedestrian arrives at a random moment in
    the stream, looks at the time until the next car reaches its line, and decides every step. Critical
    gaps and phases are drawn the way the world draws them (classical pedestrians: phase π/2).
    """
    rng = np.random.default_rng(seed)
    scenario = ScenarioConfig(
        pedestrians=PedestrianConfig(behaviour=BehaviourConfig(phase_distribution="classical"))
    )
    world = World(scenario, np.random.default_rng(seed))
    draw = world.pedestrians
    crit = np.array([draw._draw_critical_gap() for _ in range(n)])
    gap = rng.exponential(headway, n)  # time to the next car at arrival (memoryless stream)
    accepted = np.full(n, np.nan)
    waiting = np.ones(n, dtype=bool)
    for _ in range(round(600 / dt)):
        idx = np.flatnonzero(waiting)
        if idx.size == 0:
            break
        ctx = _context(gap[idx], crit[idx], np.full(idx.size, HALF_PI), dt=dt)
        go = rng.random(idx.size) < model.probability(ctx)  # type: ignore[attr-defined]
        accepted[idx[go]] = gap[idx[go]]
        waiting[idx[go]] = False
        gap -= dt
        passed = gap <= 0
        gap[passed] += rng.exponential(headway, passed.sum())
    return accepted[np.isfinite(accepted)]


@pytest.mark.parametrize("model", [GapAcceptance(), QuantumGapAcceptance()], ids=["gap", "qlb-classical"])
def test_accepted_gaps_match_calibration_targets(model: object) -> None:
    # The accepted gap is the critical gap plus the overshoot of the traffic stream, so its median grows
    # with the headway (measured: about 6.5 / 7.1 / 7.4 s for the step model at 1.25 / 2 / 2.5 s headways).
    # Field accepted gaps come from busy sites: a car every 1.2 s at the pedestrian's line (both directions).
    gaps = _accepted_gaps(model, 3000, headway=1.2, seed=3)
    assert gaps.size > 2400
    median = float(np.median(gaps))
    assert 5.0 <= median <= 6.5, median
    assert np.mean(gaps < 3.0) < 0.02
    assert 5.3 <= float(np.percentile(gaps, 85)) <= 9.4  # Brewer et al. (2006): 85th percentile 5.3–9.4 s


# ------------------------------------------------------------------ pedestrians in the world
def _rate_scenario(**rates: float) -> ScenarioConfig:
    behaviour = BehaviourConfig(decision_model="qlb", **rates)  # type: ignore[arg-type]
    return ScenarioConfig(
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(
            spawn_rate=45.0,
            cross_fraction=0.8,
            group_probability=0.0,
            max_pedestrians=160,
            behaviour=behaviour,
        ),
        duration=1000.0,
    )


def test_irrational_acts_happen_at_their_configured_rates() -> None:
    rates = {
        "distraction_rate": 0.2,
        "running_rate": 0.3,
        "hesitation_rate": 0.25,
        "turn_back_rate": 0.15,
        "jaywalk_rate": 0.2,
    }
    world, events = _run(_rate_scenario(**rates), seconds=260.0, seed=4)
    kinds: dict[str, set[int]] = defaultdict(set)
    for e in events:
        kinds[e.kind].add(e.pedestrian_id)
    spawned = world.pedestrians.next_id
    starters = kinds["start_crossing"]
    assert spawned > 150 and len(starters) > 120

    def close(count: int, n: int, rate: float) -> bool:  # within 3 binomial standard deviations
        return abs(count / n - rate) <= 3.0 * math.sqrt(rate * (1 - rate) / n)

    assert close(len(kinds["distracted"]), spawned, 0.2)
    assert close(len(kinds["run"] & starters), len(starters), 0.3)
    # Jaywalkers are a fraction of the pedestrians who intend to cross (those who reached a kerb).
    assert close(len(kinds["jaywalk"] & starters), len(starters), 0.2)
    # Hesitation and turning back happen during a crossing: count among those who got across.
    still = {int(world.pedestrians.ids[i]) for i in np.flatnonzero(world.pedestrians.state == CROSSING)}
    done = starters - still
    assert close(len(kinds["hesitate"] & done), len(done), 0.25)
    assert close(len(kinds["turn_back"] & done), len(done), 0.15)
    # Every act is a logged event of a known kind.
    assert set(kinds) <= {
        "distracted",
        "run",
        "hesitate",
        "turn_back",
        "jaywalk",
        "red_light",
        "start_crossing",
    }


def test_zero_rates_give_no_irrational_acts() -> None:
    zero = {
        "distraction_rate": 0.0,
        "running_rate": 0.0,
        "hesitation_rate": 0.0,
        "turn_back_rate": 0.0,
        "jaywalk_rate": 0.0,
        "red_light_rate": 0.0,
    }
    _, events = _run(_rate_scenario(**zero), seconds=40.0, seed=5)
    kinds = {e.kind for e in events}
    assert kinds == {"start_crossing"}


def test_turning_back_returns_to_the_start_kerb_and_crosses_again() -> None:
    spawn = PedestrianSpawn(x=118.0, side="south")
    scenario = _rate_scenario(turn_back_rate=1.0, hesitation_rate=0.0, running_rate=0.0, distraction_rate=0.0)
    scenario = ScenarioConfig(
        **{
            **scenario.__dict__,
            "pedestrians": PedestrianConfig(
                spawns=(spawn,), spawn_rate=0.0, behaviour=scenario.pedestrians.behaviour
            ),
        }
    )
    world = World(scenario, np.random.default_rng(6))
    seen: list[tuple[str, float]] = []
    min_y_after_turn = np.inf
    for _ in range(400):
        world.step(0.0)
        seen += [(e.kind, world.pedestrians.position[0, 1]) for e in world.pedestrians.events]
        if any(k == "turn_back" for k, _ in seen) and sum(k == "start_crossing" for k, _ in seen) == 1:
            min_y_after_turn = min(min_y_after_turn, world.pedestrians.position[0, 1])
    kinds = [k for k, _ in seen]
    assert kinds.count("turn_back") == 1 and kinds.count("start_crossing") == 2
    assert min_y_after_turn < world.geometry.kerb_south  # it went back onto its own (south) sidewalk
    assert world.pedestrians.position[0, 1] > world.geometry.kerb_north or not world.pedestrians.active[0]


def test_groups_cross_together() -> None:
    spawns = (
        PedestrianSpawn(x=112.0, side="south", group=7, critical_gap=3.0),
        PedestrianSpawn(x=108.0, side="south", group=7, critical_gap=9.0),  # arrives later, more careful
        PedestrianSpawn(x=111.0, side="north", group=8),
        PedestrianSpawn(x=110.0, side="north", group=8),
        PedestrianSpawn(x=109.0, side="north", group=8),
    )
    behaviour = BehaviourConfig(
        decision_model="qlb", hesitation_rate=0.0, turn_back_rate=0.0, distraction_rate=0.0
    )
    # Busy, but not so busy that no gap lets a group clear both lanes (lane by lane, at walking speed)
    # within a minute: at 900 cars/h per lane it hardly ever comes.
    scenario = ScenarioConfig(
        traffic=TrafficConfig(flow_per_lane=300.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, behaviour=behaviour),
    )
    for seed in range(3):
        _, events = _run(scenario, seconds=60.0, seed=seed)
        start = {e.pedestrian_id: e.time for e in events if e.kind == "start_crossing"}
        assert len(start) == 5
        assert start[0] == start[1]
        assert start[2] == start[3] == start[4]


def _signal_scenario(red_light_rate: float) -> ScenarioConfig:
    behaviour = BehaviourConfig(decision_model="qlb", red_light_rate=red_light_rate, jaywalk_rate=0.0)
    return ScenarioConfig(
        crossing=CrosswalkConfig(
            kind="signalised",
            width=8.0,
            signal=SignalConfig(pedestrian_green=10.0, pedestrian_red=70.0, offset=10.0),
        ),
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(
            spawn_rate=40.0,
            cross_fraction=1.0,
            group_probability=0.0,
            max_pedestrians=96,
            spawn_extent=12.0,
            behaviour=behaviour,
        ),
    )


def test_nobody_crosses_on_red_when_the_rate_is_zero() -> None:
    world, events = _run(_signal_scenario(0.0), seconds=65.0, seed=7)
    assert not any(e.kind in ("red_light", "start_crossing") for e in events)  # 65 s of red from t = 0
    assert int((world.pedestrians.state == WAITING).sum()) > 10  # many are waiting at the kerb


def test_red_light_violators_cross_at_the_configured_rate() -> None:
    _, events = _run(_signal_scenario(1.0), seconds=30.0, seed=7)
    red = {e.pedestrian_id for e in events if e.kind == "red_light"}
    starts = {e.pedestrian_id for e in events if e.kind == "start_crossing"}
    assert len(red) > 10 and red == starts
    world = World(_signal_scenario(0.3), np.random.default_rng(8))
    peds, red, arrived = world.pedestrians, set(), set()
    for _ in range(650):  # 65 s of red
        world.step(0.0)
        arrived |= {int(i) for i in peds.ids[peds.state == WAITING]}
        red |= {e.pedestrian_id for e in peds.events if e.kind == "red_light"}
    assert len(arrived) > 25
    assert abs(len(red) / len(arrived) - 0.3) <= 3.0 * math.sqrt(0.3 * 0.7 / len(arrived))


def test_same_seed_same_pedestrians() -> None:
    behaviour = BehaviourConfig(decision_model="qlb", update_force_intensity=True, phase_std=0.8)
    scenario = ScenarioConfig(
        pedestrians=PedestrianConfig(spawn_rate=40.0, spawn_extent=10.0, behaviour=behaviour)
    )
    runs = []
    for _ in range(2):
        world, events = _run(scenario, seconds=30.0, seed=9)
        runs.append((world.pedestrians.position.copy(), world.pedestrians.force_intensity.copy(), events))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2] and len(runs[0][2]) > 5
    other, _ = _run(scenario, seconds=30.0, seed=10)
    assert not np.array_equal(other.pedestrians.position, runs[0][0])


# ------------------------------------------------------------------ seed Case 2
def test_irrational_neighbour_fraction_and_intensity_update() -> None:
    pos = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0], [50.0, 0.0], [1.0, 1.0]])
    active = np.array([True, True, True, True, False])
    irrational = np.array([False, True, False, False, True])
    f = irrational_neighbour_fraction(pos, active, irrational, radius=10.0)
    np.testing.assert_allclose(f, [0.5, 0.0, 0.5, 0.0, 0.0])
    k = updated_ped_intensity(0.42, f)
    assert k[1] == pytest.approx(0.42) and k[3] == pytest.approx(0.42)
    assert k[0] > 0.42


def test_force_update_raises_intensity_near_irrational_pedestrians() -> None:
    behaviour = BehaviourConfig(
        decision_model="qlb", update_force_intensity=True, running_rate=0.5, jaywalk_rate=0.3
    )
    scenario = ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=40.0, behaviour=behaviour))
    world = World(scenario, np.random.default_rng(11))
    peds: PedestrianPopulation = world.pedestrians
    raised = 0
    for _ in range(300):
        world.step(0.0)
        base = scenario.pedestrians.social_force.ped_intensity
        if peds.irrational_now().any():
            raised += int(np.sum(peds.force_intensity[peds.active] > base + 1e-9))
        assert np.all(peds.force_intensity >= base - 1e-12)
    assert raised > 0
    off = World(
        ScenarioConfig(
            pedestrians=PedestrianConfig(
                spawn_rate=40.0, behaviour=BehaviourConfig(decision_model="qlb", running_rate=0.5)
            )
        ),
        np.random.default_rng(11),
    )
    for _ in range(100):
        off.step(0.0)
    assert np.all(off.pedestrians.force_intensity == scenario.pedestrians.social_force.ped_intensity)


def test_distracted_pedestrian_takes_a_gap_an_attentive_one_refuses() -> None:
    spawns = (
        PedestrianSpawn(x=120.0, side="south", critical_gap=6.0, distracted=False),
        PedestrianSpawn(x=120.0, side="north", critical_gap=6.0, distracted=True),
    )
    behaviour = BehaviourConfig(
        decision_model="gap", turn_back_rate=0.0, hesitation_rate=0.0, running_rate=0.0
    )
    scenario = ScenarioConfig(
        ego=EgoConfig(speed=0.0, x=20.0),
        traffic=TrafficConfig(flow_per_lane=0.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, behaviour=behaviour),
    )
    world = World(scenario, np.random.default_rng(12))
    peds = world.pedestrians
    world.step(0.0)  # spawns both
    peds.state[:2] = WAITING  # put them at their kerb points, about to decide
    peds.position[:2] = peds.waypoint[:2]
    peds.velocity[:2] = 0.0
    # A car in the north (−x) lane 5 s from the lines: under the attentive pedestrian's 6 s critical gap;
    # the distracted one (critical gap x 0.7, view 1 s late), for whom it is the near lane, takes it. The
    # south-lane car is 12 s away, far enough for either to clear its lane.
    x = peds.crossing_x[:2]
    cars = CarSnapshot(
        x=np.array([x[0] - 120.0 - 2.25, x[1] + 50.0 + 2.25]),
        direction=np.array([1.0, -1.0]),
        speed=np.array([10.0, 10.0]),
        half_length=np.array([2.25, 2.25]),
        boxes=np.zeros((0, 4)),
        lane=np.array([0, 1]),
    )
    peds.step(world.time + 0.1, cars, None)
    assert peds.state[0] == WAITING and peds.state[1] == CROSSING
