"""The learned intent model: JSON weights checked against their manifest, deterministic training, wrappers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from crossing_env.env import CrossingEnv
from crossing_env.observation import CROSSING_INTENT_KEY, CROSSING_INTENTION_KEY
from predictors.intention import ClassicalIntention, QLBIntention
from predictors.learned_intent import FEATURES, LearnedIntention
from predictors.learned_intent_train import EVAL_SEEDS, train
from predictors.learned_intent_weights import (
    CROSSING_INTENT_BOUND_KEY,
    MANIFEST_PATH,
    WEIGHTS_PATH,
    IntentWeightsError,
    read_weights,
    sha256_bytes,
)
from scenarios import load_scenario


def test_shipped_weights_are_small_json_matching_the_manifest() -> None:
    data = WEIGHTS_PATH.read_bytes()
    assert len(data) <= 1_000_000
    assert json.loads(MANIFEST_PATH.read_text())[WEIGHTS_PATH.name] == sha256_bytes(data)
    weights = read_weights()
    assert weights["features"] == list(FEATURES)
    for head in weights["heads"].values():
        assert len(head["coef"]) == len(FEATURES)
    assert set(weights["release"]["models"]) == {"learned", "qlb", "classical"}
    assert min(weights["training"]["seeds"]) > max(EVAL_SEEDS) or max(weights["training"]["seeds"]) < min(
        EVAL_SEEDS
    )


def test_tampered_weights_are_refused(tmp_path) -> None:
    path = tmp_path / WEIGHTS_PATH.name
    manifest = tmp_path / MANIFEST_PATH.name
    text = WEIGHTS_PATH.read_text().replace('"l2": 0.0001', '"l2": 0.001', 1)
    assert text != WEIGHTS_PATH.read_text()
    path.write_text(text)
    manifest.write_text(MANIFEST_PATH.read_text())
    with pytest.raises(IntentWeightsError, match="does not match"):
        read_weights(path)
    manifest.write_text(json.dumps({path.name: sha256_bytes(path.read_bytes())}))
    assert read_weights(path)["format"]  # a deliberate change with its new sum loads


def test_training_is_deterministic_and_refuses_evaluation_seeds() -> None:
    kwargs = {"episodes": 1, "seed": 7, "max_steps": 150, "worlds": ["busy_zebra"]}
    first, second = train(**kwargs), train(**kwargs)
    assert json.dumps(first, sort_keys=True) == json.dumps(second, sort_keys=True)
    assert first["heads"]["intent"]["samples"] > 0
    with pytest.raises(ValueError, match="overlap the evaluation seeds"):
        train(episodes=2, seed=min(EVAL_SEEDS) - 1, max_steps=5, worlds=["busy_zebra"])


@pytest.mark.parametrize("cls", [LearnedIntention, QLBIntention, ClassicalIntention])
def test_wrappers_add_intent_and_bound(cls) -> None:
    env = cls(CrossingEnv(load_scenario("busy_zebra")))
    obs, _ = env.reset(seed=3)
    for _ in range(30):
        obs, *_ = env.step(np.zeros(1, dtype=np.float32))
    assert obs in env.observation_space
    present = obs["pedestrians"][:, 0] > 0.5
    assert present.any()
    for key in (CROSSING_INTENTION_KEY, CROSSING_INTENT_KEY):
        assert np.all(obs[key][~present] == 0.0)
        assert np.all((obs[key] >= 0.0) & (obs[key] <= 1.0))
    assert 0.0 <= float(obs[CROSSING_INTENT_BOUND_KEY][0]) < 0.5
    env.close()


def test_learned_intent_separates_crossers_from_leavers() -> None:
    """Someone on the road gets a high intent; someone walking away from the road after crossing a low one."""
    env = LearnedIntention(CrossingEnv(load_scenario("zebra_case1")))
    obs, _ = env.reset(seed=1)
    ped = np.zeros_like(obs["pedestrians"])
    hist = np.zeros_like(obs["pedestrian_history"])
    ego_y = env._scene.kerb_low  # negative: the south kerb relative to the ego
    ped[0] = [1, 20.0, 0.0, 0.0, 1.3, 1, 0, 1]  # on the zebra, crossing
    ped[1] = [1, 20.0, ego_y - 3.0, 0.0, -1.3, 0, 0, 0]  # on the sidewalk, walking away
    hist[0, :, 1] = np.linspace(ego_y - 1.0, 0.0, hist.shape[1])
    hist[1, :, 1] = np.linspace(ego_y + 1.0, ego_y - 3.0, hist.shape[1])  # came off the road
    hist[:, :, 0] = 20.0
    out = env.observation(dict(obs, pedestrians=ped, pedestrian_history=hist))
    assert out[CROSSING_INTENT_KEY][0] > 0.9
    assert out[CROSSING_INTENT_KEY][1] < 0.05
    env.close()
