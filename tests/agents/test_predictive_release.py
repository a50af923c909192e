"""Release by a real intent predictor: its published risk bound, and never against the law."""

from __future__ import annotations

import numpy as np

from agents import PredictiveYielding
from predictors.learned_intent_weights import CROSSING_INTENT_BOUND_KEY
from tests.agents.test_policies import K, accel, crossing_centre, make_obs


def _with(obs: dict[str, np.ndarray], intent: float, bound: float | None) -> dict[str, np.ndarray]:
    values = np.r_[intent, np.zeros(K - 1)].astype(np.float32)
    out = dict(obs, crossing_intent=values, crossing_intention=values)
    if bound is not None:
        out[CROSSING_INTENT_BOUND_KEY] = np.array([bound], dtype=np.float32)
    return out


def test_certain_non_crosser_releases_a_waiting_car_only_where_the_law_allows() -> None:
    at_kerb = {"dx": crossing_centre(0.5), "dy": -2.6, "w": 1}
    on_zebra = {"dx": crossing_centre(0.5), "dy": -1.0, "vy": 1.3, "oc": 1, "road": 1}
    stepping = {"dx": crossing_centre(0.5), "dy": -2.2, "vy": 0.8}
    # The car stands at the stop line.
    waiting_car = make_obs(0.0, 0.5, [at_kerb])
    assert accel(PredictiveYielding()(_with(waiting_car, 0.5, 0.05)))[0] <= 0.0  # unsure: keeps waiting
    assert accel(PredictiveYielding()(_with(waiting_car, 0.0, 0.05)))[0] > 0.0  # certain: drives on
    for ped in (on_zebra, stepping):
        obs = _with(make_obs(0.0, 0.5, [ped]), 0.0, 0.05)
        assert accel(PredictiveYielding()(obs))[0] <= 0.0, ped  # the duty is visible: it stays


def test_the_published_bound_replaces_the_config_threshold() -> None:
    at_kerb = {"dx": crossing_centre(25.0), "dy": -2.6, "w": 1}
    base = make_obs(12.0, 25.0, [at_kerb])
    policy = PredictiveYielding()
    assert policy.config.release_threshold >= 0.1
    assert accel(policy(_with(base, 0.1, None)))[0] >= 0.0  # no bound published: the config's applies
    assert accel(policy(_with(base, 0.1, 0.05)))[0] < -2.0  # above the predictor's own bound: stop
    assert accel(policy(_with(base, 0.04, 0.05)))[0] >= 0.0
    assert policy.release_bound() is not None
