"""Smoke test of the Stable-Baselines3 PPO recipe: a few hundred steps, its files, one scored episode."""

from __future__ import annotations

import csv
import importlib.util
import itertools
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="stable-baselines3 (test extra) not installed")

REPO = Path(__file__).resolve().parents[2]


def _load_recipe(monkeypatch: pytest.MonkeyPatch, name: str) -> types.ModuleType:
    """`examples/ppo_crossing.py` imported as module `name` (registered while the test runs)."""
    spec = importlib.util.spec_from_file_location(name, REPO / "examples" / "ppo_crossing.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)  # its dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


def _train(tmp_path: Path, *options: str) -> subprocess.CompletedProcess[str]:
    """Run the recipe with `options` (single-threaded, as the determinism it is tested for needs)."""
    proc = subprocess.run(
        [sys.executable, str(REPO / "examples" / "ppo_crossing.py"), *options, "--no-progress"],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1"),
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def test_ppo_example_trains_logs_plots_and_evaluates(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _train(
        tmp_path,
        *("--timesteps", "512", "--n-envs", "2", "--n-steps", "128", "--batch-size", "64"),
        *("--bc-steps", "64", "--dagger-rounds", "1", "--eval-every", "256", "--eval-episodes", "1"),
        *("--scenarios", "zebra_case1,midblock_jaywalker", "--out", str(out)),
    )
    assert "trained PPO (ppo) for 512 steps" in proc.stdout
    assert "warm start: imitated the yielding policy on 64 steps" in proc.stdout
    assert "DAgger round 1/1: 128 labelled steps" in proc.stdout  # the loop ran: 64 + 64 steps labelled
    assert "collision rate [95% CI]" in proc.stdout and "mean return" in proc.stdout
    model = out / "model.zip"
    assert model.is_file() and model.stat().st_size > 1000
    assert (out / "model.vecnormalize.npz").is_file() and (out / "step_256.zip").is_file()
    assert (out / "model.policy.npz").is_file() and (out / "step_256.policy.npz").is_file()
    assert not list(out.glob("*.pkl")), "statistics are data (npz), never pickle"
    assert (out / "learning_curve.png").stat().st_size > 1000
    header = (out / "episodes.csv").read_text().splitlines()[0]
    assert header == (
        "step,scenario,return,cost,collision,obligations,violations,delay,duration,multiplier,wall_s"
    )
    assert (out / "progress.csv").is_file()


def _short_lagrangian_run(tmp_path: Path, name: str, seed: int) -> Path:
    out = tmp_path / name
    _train(
        tmp_path,
        *("--algo", "ppo_lagrangian", "--timesteps", "512", "--n-envs", "2", "--n-steps", "128"),
        *("--batch-size", "64", "--bc-steps", "64", "--eval-every", "0", "--eval-episodes", "0"),
        *("--seed", str(seed), "--scenarios", "ncap_cpna,zebra_case1", "--out", str(out)),
    )
    return out


def _episodes_without_wall_clock(out: Path) -> list[dict[str, str]]:
    with (out / "episodes.csv").open() as fh:
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in csv.DictReader(fh)]


def test_training_with_the_same_seed_gives_the_same_policy(tmp_path: Path) -> None:
    """docs/rl.md relies on it: on one installation a seed fixes the warm start, PPO and λ."""
    first = _short_lagrangian_run(tmp_path, "a", seed=5)
    again = _short_lagrangian_run(tmp_path, "b", seed=5)
    other = _short_lagrangian_run(tmp_path, "c", seed=6)
    with np.load(first / "model.policy.npz") as a, np.load(again / "model.policy.npz") as b:
        assert a.files == b.files
        for k in a.files:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert _episodes_without_wall_clock(first) == _episodes_without_wall_clock(again)
    with np.load(first / "model.policy.npz") as a, np.load(other / "model.policy.npz") as c:
        assert any(a[k].shape == c[k].shape and not np.array_equal(a[k], c[k]) for k in a.files)


def test_ppo_example_rejects_bad_timesteps(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, str(REPO / "examples" / "ppo_crossing.py"), "--timesteps", "-5"],
        cwd=tmp_path,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2
    assert "'-5'" in proc.stderr


def test_ppo_lagrangian_raises_its_multiplier_while_the_cost_exceeds_the_budget(tmp_path: Path) -> None:
    """A zero budget where episodes cost something: λ must grow from 0 during training.

    With almost no exploration noise the untrained actor holds its speed (action ≈ 0), and the NCAP dummy
    is timed to meet a car that does: near misses and collisions, so the cost exceeds the budget.
    """
    out = tmp_path / "lag"
    proc = _train(
        tmp_path,
        *("--algo", "ppo_lagrangian", "--cost-budget", "0", "--lambda-lr", "0.5"),
        *("--timesteps", "1536", "--n-envs", "2", "--n-steps", "256", "--batch-size", "128"),
        *("--eval-every", "0", "--eval-episodes", "0", "--seed", "3", "--log-std-init", "-3"),
        *("--scenarios", "ncap_cpna", "--out", str(out)),
    )
    with (out / "episodes.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    costs = [float(r["cost"]) for r in rows]
    lambdas = [float(r["multiplier"]) for r in rows]
    assert rows and sum(costs) > 0
    assert lambdas[0] == 0.0 and lambdas[-1] > 0.0 and lambdas == sorted(lambdas)
    assert "final λ" in proc.stdout


def test_ppo_time_reward_replaces_the_cost_of_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--time-reward`` reaches the training env's reward (the shielded recipe weighs time more)."""
    import numpy as np

    module = _load_recipe(monkeypatch, "ppo_crossing_time")
    assert module.parse_args(["--time-reward", "-1"]).time_reward == -1.0
    assert module.parse_args([]).time_reward is None
    terms = {}
    for weight in (None, -1.0):
        env = module.make_env(("zebra_case1",), False, "shielded", None, 2.0, weight)
        env.reset(seed=0)
        terms[weight] = env.step(np.zeros(1, dtype=np.float32))[4]["rewards"]["time"]
        env.close()
    assert terms[None] == pytest.approx(-0.2 * 0.1)  # the env's default: −0.2 per second, 0.1 s steps
    assert terms[-1.0] == pytest.approx(-1.0 * 0.1)


def test_dagger_rounds_are_driven_by_the_actor_and_labelled_by_the_rule(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A DAgger round steps the env with the actor's action and records the yielding policy's as the label."""
    import numpy as np

    from crossing_env.observation import EGO_KEY, EgoColumn

    module = _load_recipe(monkeypatch, "ppo_crossing_dagger")
    assert module.parse_args(["--bc-steps", "10", "--dagger-rounds", "2"]).dagger_rounds == 2
    env = module.make_env(("zebra_case1",), False)
    keys = list(env.observation_space.spaces)
    steps = 60
    rule_obs, rule_labels = module._demonstrations(env, keys, steps, 7)
    brake_obs, brake_labels = module._demonstrations(env, keys, steps, 7, lambda obs: np.float32(-1.0))
    env.close()
    assert len(rule_labels) == len(brake_labels) == steps
    speed = EgoColumn.SPEED
    rule_speed = np.array([o[speed] for o in rule_obs[EGO_KEY]])
    brake_speed = np.array([o[speed] for o in brake_obs[EGO_KEY]])
    assert rule_speed[0] == brake_speed[0] > 5.0  # the same episode start
    assert brake_speed[-1] < 0.5 < rule_speed[-1]  # the actor's full braking drove the env, not the rule
    assert max(brake_labels) > -1.0  # the labels are the rule's, not the actor's constant -1
    assert not np.allclose(rule_labels, brake_labels)  # the rule answers the states the actor led to


def test_dagger_rounds_of_different_training_seeds_drive_different_episodes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """No two DAgger rounds, and no two training seeds, share an episode seed (nor the warm start's)."""
    module = _load_recipe(monkeypatch, "ppo_crossing_seeds")
    steps, seeds, rounds = 20_000, range(3), range(4)
    spans = [
        range(module.dagger_first_seed(s, r, steps), module.dagger_first_seed(s, r, steps) + steps)
        for s in seeds
        for r in rounds
    ]
    spans += [range(s * 100_003, s * 100_003 + steps) for s in seeds]  # the warm starts' demonstrations
    starts = sorted((span.start, span.stop) for span in spans)
    assert all(stop <= nxt for (_, stop), (nxt, _) in itertools.pairwise(starts))
