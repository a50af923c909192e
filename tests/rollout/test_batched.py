"""Batched episodes: a policy that declares ``batched`` gives every episode of a batch what it gives alone."""

from __future__ import annotations

import numpy as np
import pytest

from agents import make_policy, policy_is_batched
from crossing_eval import tasks as tasks_module
from crossing_eval.runners import EpisodeFailed, run_batch_guarded
from crossing_eval.tasks import EpisodeTask, batches, episode_seed, make_tasks, run_batch, run_episode
from rollout import build_policy, make_env, run_episodes
from rollout import run_episode as rollout_episode

# Episodes of different lengths, so that some end while others of the batch still run.
SCENARIOS = ("zebra_case1", "ncap_cpfa")
BATCHED = ("yielding", "predictive_yielding", "always_cautious", "ppo_shielded", "ttc_brake")


@pytest.mark.parametrize("policy", BATCHED)
def test_a_batch_gives_every_episode_what_it_gives_alone(policy: str) -> None:
    for scenario in SCENARIOS:
        seeds = [episode_seed(2024, scenario, e) for e in range(3)]
        envs = [make_env(scenario, *_wrappers(policy))[0] for _ in seeds]
        alone = [rollout_episode(envs[0], s, policy=build_policy(policy, envs[0])) for s in seeds]
        together = run_episodes(envs, seeds, build_policy(policy, envs[0]))
        assert policy_is_batched(build_policy(policy, envs[0]))
        assert len({len(e.actions) for e in alone}) > 1 or scenario == "zebra_case1"
        for a, b in zip(alone, together, strict=True):
            assert b.actions == a.actions
            assert b.result == a.result
            assert b.episode_return == a.episode_return
            assert b.initial_speed == a.initial_speed
            last_b, last_a = b.final_ground_truth, a.final_ground_truth
            np.testing.assert_array_equal(last_b.ego_position, last_a.ego_position)


def _wrappers(policy: str) -> tuple[str, str]:
    return ("qlb", "s-cgru") if policy in ("yielding", "predictive_yielding") else ("none", "none")


def test_the_evaluation_gives_the_same_records_batched_or_not() -> None:
    tasks = make_tasks(["ncap_cpna"], ["yielding", "random"], 3, 11)
    groups = list(batches(tasks))
    assert [len(g) for g in groups] == [3, 3]  # one batch per (scenario, policy, wrappers)
    records = [r for g in groups for r in run_batch(g)]
    single = [run_episode(t) for t in tasks]
    assert [r.task for r in records] == tasks
    assert [r.actions for r in records] == [r.actions for r in single]
    assert [r.result for r in records] == [r.result for r in single]
    assert not policy_is_batched(make_policy("random"))  # it ran one by one, and still the same


def test_batches_are_lazy_and_never_mix_scenarios_policies_or_wrappers() -> None:
    tasks = make_tasks(["zebra_case1", "busy_zebra"], ["yielding", "constant_speed"], 10, 3)
    groups = list(batches(tasks, size=4))
    assert [t for g in groups for t in g] == tasks
    assert max(len(g) for g in groups) == 4
    for g in groups:
        assert len({(t.scenario, t.policy, t.predictor, t.intention) for t in g}) == 1
    read = []

    def lazy() -> object:
        for t in tasks:
            read.append(t)
            yield t

    first = next(batches(lazy(), size=4))
    assert len(first) == 4 and len(read) == 5  # one task read past the batch
    with pytest.raises(ValueError, match="one scenario, policy and wrappers"):
        run_batch([tasks[0], tasks[-1]])


def test_a_failing_batch_names_the_episode_that_failed(monkeypatch: pytest.MonkeyPatch) -> None:
    tasks = [EpisodeTask("zebra_case1", "constant_speed", e, e) for e in range(3)]
    real = tasks_module.run_episode

    def batch_breaks(*args: object, **kwargs: object) -> object:
        raise RuntimeError("the batch broke")

    class Unpicklable(Exception):  # defined in a function: cannot be pickled by reference
        pass

    def fails_on_seed_1(task: EpisodeTask) -> object:
        if task.seed == 1:
            raise Unpicklable("lost in a worker")
        return real(task)

    monkeypatch.setattr("rollout.run_episodes", batch_breaks)
    monkeypatch.setattr("crossing_eval.runners.run_episode", fails_on_seed_1)
    # Run again one by one, the error names the episode that raised, not the batch.
    with pytest.raises(EpisodeFailed, match=r"episode 1 of scenario 'zebra_case1'.*lost in a worker"):
        run_batch_guarded(tasks)
    monkeypatch.setattr("crossing_eval.runners.run_episode", real)
    assert [r.task for r in run_batch_guarded(tasks)] == tasks  # the batch broke, the episodes did not


def test_run_episodes_needs_one_seed_per_env() -> None:
    env = make_env("zebra_case1")[0]
    with pytest.raises(ValueError, match="one seed per env"):
        run_episodes([env], [1, 2], make_policy("constant_speed"))
    with pytest.raises(ValueError, match="one seed per env"):
        run_episodes([], [], make_policy("constant_speed"))


def test_spare_envs_are_kept_for_the_last_keys_only(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tasks_module, "_SPARE_ENVS", {})
    for scenario in ("zebra_case1", "ncap_cpna", "busy_zebra"):
        envs, _ = tasks_module._batch_envs(EpisodeTask(scenario, "constant_speed", 0, 0), 3)
        assert len({id(e) for e in envs}) == 3  # one env per episode of the batch
    assert [key[0] for key in tasks_module._SPARE_ENVS] == ["ncap_cpna", "busy_zebra"]
    again, _ = tasks_module._batch_envs(EpisodeTask("busy_zebra", "yielding", 0, 0, "none", "none"), 2)
    assert again[1] is tasks_module._SPARE_ENVS[("busy_zebra", "none", "none")][0]  # reused, not rebuilt
