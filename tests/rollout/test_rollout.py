"""The rollout layer: one wrapper table, one assembly, one episode loop, and the `Policy` protocol."""

from __future__ import annotations

import numpy as np
import pytest

from agents import Policy, as_policy, make_policy, policy_names
from agents.policy import FunctionPolicy
from crossing_eval.tasks import EpisodeTask
from crossing_eval.tasks import run_episode as eval_episode
from rollout import (
    INTENTION_WRAPPERS,
    TRAJECTORY_WRAPPERS,
    RolloutSpec,
    WrapperError,
    build,
    frames,
    make_env,
    run_episode,
    wrappers_for,
)

SCENARIO = "zebra_case1"


def test_predicting_policy_gets_default_wrappers_others_none() -> None:
    assert wrappers_for("predictive_yielding", None, None) == ("qlb", "s-cgru")
    assert wrappers_for("constant_speed", None, None) == ("none", "none")
    assert wrappers_for("yielding", "classical", "none") == ("classical", "none")


@pytest.mark.parametrize(("intention", "predictor"), [("psychic", "none"), ("none", "crystal-ball")])
def test_unknown_wrapper_is_an_error(intention: str, predictor: str) -> None:
    with pytest.raises(WrapperError, match=r"psychic|crystal-ball"):
        make_env(SCENARIO, intention, predictor)


def test_checkpoint_that_cannot_load_is_an_error(tmp_path) -> None:
    bad = tmp_path / "model.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(WrapperError, match=r"model\.pt"):
        make_env(SCENARIO, "none", str(bad))


def test_missing_wrapper_module_is_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from rollout import wrappers

    monkeypatch.setitem(wrappers.INTENTION_WRAPPERS, "broken", wrappers.WrapperEntry("no_such_module:Thing"))
    with pytest.raises(WrapperError, match="no_such_module"):
        make_env(SCENARIO, "broken", "none")


def test_every_table_entry_builds_and_adds_its_key() -> None:
    for name in INTENTION_WRAPPERS:
        env, used = make_env(SCENARIO, name, "none")
        assert used == [f"intention:{name}"] and "crossing_intention" in env.observation_space.spaces
        env.close()
    for name in TRAJECTORY_WRAPPERS:
        env, used = make_env(SCENARIO, "none", name)
        assert used == [f"trajectory:{name}"] and "predicted_paths" in env.observation_space.spaces
        env.close()


def test_same_seed_same_episode_and_policy_is_reset() -> None:
    run = build(RolloutSpec(scenario=SCENARIO, policy="random"))
    a = run_episode(run.env, 5, policy=run.policy, max_steps=40)
    run_episode(run.env, 6, policy=run.policy, max_steps=40)  # advances the policy's generator
    b = run_episode(run.env, 5, policy=run.policy, max_steps=40)
    assert a.actions == b.actions and a.result == b.result and len(set(a.actions)) > 1
    c = run_episode(run.env, 6, policy=run.policy, max_steps=40)
    assert c.actions != a.actions  # seeds differ, so do the episodes


def test_replaying_the_actions_reproduces_the_episode() -> None:
    run = build(RolloutSpec(scenario=SCENARIO, policy="yielding"))
    first = run_episode(run.env, 3, policy=run.policy)
    again = run_episode(run.env, 3, actions=first.actions)
    assert again.result == first.result and again.episode_return == pytest.approx(first.episode_return)


def test_frames_need_exactly_one_source() -> None:
    env, _ = make_env(SCENARIO)
    with pytest.raises(ValueError, match="exactly one"):
        next(frames(env, 0))


def test_evaluation_runs_the_same_loop() -> None:
    """A `crossing-eval` task's record is the rollout's episode for the same policy and seed."""
    task = EpisodeTask(scenario=SCENARIO, policy="yielding", episode=0, seed=11)
    record = eval_episode(task)
    run = build(RolloutSpec(scenario=SCENARIO, policy="yielding"))
    episode = run_episode(run.env, 11, policy=run.policy)
    assert record.result == episode.result and record.actions == episode.actions


def test_policy_protocol() -> None:
    for name in policy_names():
        assert isinstance(make_policy(name), Policy), name
    adapted = as_policy(lambda obs: 0.5)
    assert isinstance(adapted, FunctionPolicy) and isinstance(adapted, Policy)
    np.testing.assert_array_equal(adapted({}), np.array([0.5], dtype=np.float32))
    with pytest.raises(TypeError, match="int"):
        as_policy(3)
