"""Train Stable-Baselines3 PPO on `crossing_env/Crossing-v0` over all built-in scenarios, then evaluate it.

    pip install -e ".[rl]"
    python examples/ppo_crossing.py --timesteps 500000 --n-envs 4 --out runs/ppo --seed 0
    python examples/ppo_crossing.py --algo ppo_lagrangian --cost-budget 2 ...   # constrained
    python examples/ppo_crossing.py --algo shielded ...                          # through the shield

Three learners (``--algo``):

- ``ppo``: plain PPO on the env's reward;
- ``ppo_lagrangian``: PPO-Lagrangian, the constraint "expected episode cost ≤ ``--cost-budget``" learned
  with no rule in the loop: the reward is shaped to r − λ·cost (`crossing_env.constrained.LagrangianReward`,
  cost = ``info["cost"]``) and λ follows dual ascent once per rollout, λ ← max(0, λ + lr·(J̄_C − d)) with J̄_C
  the mean cost of the episodes that ended in the rollout (the lightweight SB3 pattern: no separate cost
  critic; the penalty reaches the policy through the value function);
- ``shielded``: PPO acting through the yielding policy's safety envelope (`agents.shield`): an action
  above the envelope's limit is replaced by the limit before the env sees it (post-posed shield); PPO
  stores and learns from the action it asked for.

PPO uses SB3's ``MultiInputPolicy`` (its ``CombinedExtractor`` flattens each Box of the dict observation).
Every reset draws one built-in scenario (`ScenarioMix`), so the policy meets them all. ``VecNormalize``
standardises the observation (positions reach ±500 m) and the reward. Envs run in a ``DummyVecEnv`` by
default (``--subproc`` for worker processes; on a 2-core machine they cost more than they save).

Outputs in ``--out``: ``model.zip`` + ``model.vecnormalize.npz`` (the pair ``crossing-eval --policies
sb3:OUT/model.zip`` loads), ``model.policy.npz`` (the same actor as plain data, `agents.mlp`: ``crossing-eval
--policies mlp:OUT/model.policy.npz`` runs it with numpy only, through the shield if it was trained through
it), ``step_N.zip`` + statistics + ``step_N.policy.npz`` (checkpoints every ``--eval-every`` steps, to select
from), ``progress.csv`` (SB3's logger), ``episodes.csv`` (one row per training episode: env step, return
without the Lagrangian penalty, episode cost, collision, yield obligations and violations, delay, duration,
λ, wall-clock seconds) and ``learning_curve.png``. The final evaluation
runs `crossing-eval`'s own episode code (`crossing_eval.tasks`) on its default seeds and prints the mean
return with the metrics.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

# Heavy imports (torch, SB3, the env) happen inside the functions, so bad arguments fail fast.

ALGOS = ("ppo", "ppo_lagrangian", "shielded")
"""The learners of ``--algo``."""


@dataclass(frozen=True)
class Args:
    """Command-line settings (CleanRL style)."""

    timesteps: int = 200_000
    """Total environment steps of training."""
    algo: str = "ppo"
    """Learner: ``ppo``, ``ppo_lagrangian`` (cost constraint by a Lagrange multiplier) or ``shielded``."""
    cost_budget: float = 2.0
    """PPO-Lagrangian's budget d on the expected episode cost (`crossing_env.constrained.CostBudget`)."""
    lambda_lr: float = 0.05
    """Dual-ascent step of the Lagrange multiplier per rollout."""
    residual: float = 0.0
    """``shielded`` only: > 0 makes the action a residual on the rule's acceleration, this many m/s² per unit
    (0: the action is the acceleration itself)."""
    residual_offset: float = 0.0
    """``--residual`` only: the residual asked for is offset + action, clipped to [−1, 1]; 1 starts the
    actor (action ≈ 0) at the most the shield's envelope allows, so it learns where holding back pays."""
    scenarios: tuple[str, ...] = ()
    """Scenarios drawn per reset (empty: every built-in one)."""
    n_envs: int = 4
    """Parallel environments."""
    subproc: bool = False
    """Run the envs in worker processes (SubprocVecEnv, forkserver) instead of one process."""
    n_steps: int = 512
    """Rollout length per env and update (SB3 `n_steps`)."""
    batch_size: int = 256
    """Minibatch size (SB3 `batch_size`)."""
    learning_rate: float = 3e-4
    """Adam learning rate."""
    gamma: float = 0.995
    """Discount factor (0.995: a 20 s horizon at 0.1 s steps, the time a stop at the crossing takes)."""
    time_reward: float | None = None
    """Training reward per second of simulated time (`RewardConfig.time`; None: the env's default)."""
    predictors: bool = False
    """Train with the QLB intention and S-CGRU trajectory wrappers on."""
    bc_steps: int = 0
    """Warm start: env steps of the rule-based yielding policy whose actions the actor imitates before
    PPO (behaviour cloning; 0 = PPO from scratch)."""
    dagger_rounds: int = 0
    """After the warm start: rounds of DAgger (Ross et al. 2011), each ``--bc-steps`` env steps driven by
    the actor's own greedy action while the yielding policy, fed the same observations, labels every step;
    the actor is refitted on all labels so far. It teaches the actor the states its own mistakes lead to,
    which plain imitation of the rule's drives never shows it (0: none)."""
    log_std_init: float = 0.0
    """Initial log standard deviation of the Gaussian actions (lower after a warm start)."""
    seed: int = 0
    """Seed of PPO and the envs."""
    eval_every: int = 50_000
    """Steps between checkpoints (``step_N.zip`` + statistics) to select the shipped policy from (0: none)."""
    eval_episodes: int = 5
    """Episodes per scenario in the final evaluation (0 = skip), on `crossing-eval`'s default seeds."""
    out: Path = Path("runs/ppo")
    """Output folder."""
    progress: bool = True
    """Show SB3's progress bar."""


def parse_args(argv: list[str] | None = None) -> Args:
    """Parse the command line into `Args` (argparse exits with 2 on bad values)."""
    from crossing_common.cli import DefaultsHelpFormatter, int_at_least

    positive, non_negative = int_at_least(1), int_at_least(0)
    d = Args()
    p = argparse.ArgumentParser(
        description="PPO (Stable-Baselines3) on crossing_env/Crossing-v0",
        formatter_class=DefaultsHelpFormatter,
    )
    p.add_argument("--timesteps", type=positive, default=d.timesteps, help="training environment steps")
    p.add_argument("--algo", choices=ALGOS, default=d.algo, help="learner (see the module docstring)")
    p.add_argument(
        "--cost-budget", type=float, default=d.cost_budget, help="episode cost budget (Lagrangian)"
    )
    p.add_argument("--lambda-lr", type=float, default=d.lambda_lr, help="multiplier step per rollout")
    p.add_argument(
        "--residual",
        type=float,
        default=d.residual,
        help="shielded: action = rule + RESIDUAL x action (m/s^2)",
    )
    p.add_argument(
        "--residual-offset",
        type=float,
        default=d.residual_offset,
        help="residual: request clip(OFFSET + action, -1, 1) (1: start at the envelope's maximum)",
    )
    p.add_argument(
        "--scenarios", default="", help="comma-separated scenarios drawn per reset (default: all built-in)"
    )
    p.add_argument("--n-envs", type=positive, default=d.n_envs, help="parallel envs")
    p.add_argument("--subproc", action="store_true", help="envs in worker processes (SubprocVecEnv)")
    p.add_argument("--n-steps", type=positive, default=d.n_steps, help="rollout steps per env and update")
    p.add_argument("--batch-size", type=positive, default=d.batch_size, help="PPO minibatch size")
    p.add_argument("--learning-rate", type=float, default=d.learning_rate, help="Adam learning rate")
    p.add_argument("--gamma", type=float, default=d.gamma, help="discount factor")
    p.add_argument(
        "--time-reward", type=float, default=d.time_reward, help="reward per simulated s (default: env's)"
    )
    p.add_argument("--predictors", action="store_true", help="train with the prediction wrappers on")
    p.add_argument(
        "--bc-steps", type=non_negative, default=d.bc_steps, help="warm start: imitate the yielding policy"
    )
    p.add_argument(
        "--dagger-rounds",
        type=non_negative,
        default=d.dagger_rounds,
        help="after --bc-steps: DAgger rounds driven by the actor, labelled by the yielding policy",
    )
    p.add_argument("--log-std-init", type=float, default=d.log_std_init, help="initial log std of actions")
    p.add_argument("--seed", type=int, default=d.seed, help="random seed")
    p.add_argument("--eval-every", type=non_negative, default=d.eval_every, help="steps between checkpoints")
    p.add_argument(
        "--eval-episodes", type=non_negative, default=d.eval_episodes, help="final evaluation episodes each"
    )
    p.add_argument("--out", type=Path, default=d.out, help="output folder")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    a = p.parse_args(argv)
    from scenarios import list_scenarios

    builtin = sorted(list_scenarios())
    names = tuple(s.strip() for s in a.scenarios.split(",") if s.strip()) or tuple(builtin)
    for n in names:
        if n not in builtin and not (n.endswith(".toml") and Path(n).is_file()):
            p.error(f"argument --scenarios: unknown scenario {n!r}; built-in: {', '.join(builtin)}")
    if not 0.0 < a.gamma <= 1.0 or not a.learning_rate > 0:
        p.error(f"--gamma must be in (0, 1] and --learning-rate > 0, got {a.gamma!r}, {a.learning_rate!r}")
    if (a.residual and a.algo != "shielded") or not a.residual >= 0:
        p.error(f"--residual must be >= 0 and needs --algo shielded, got {a.residual!r} with {a.algo!r}")
    if a.residual_offset and not a.residual:
        p.error(f"--residual-offset needs --residual > 0, got offset {a.residual_offset!r}")
    if not -1.0 <= a.residual_offset <= 1.0:
        p.error(f"--residual-offset must be in [-1, 1], got {a.residual_offset!r}")
    if not a.cost_budget >= 0 or not a.lambda_lr >= 0:
        p.error(f"--cost-budget and --lambda-lr must be >= 0, got {a.cost_budget!r}, {a.lambda_lr!r}")
    if a.dagger_rounds and not a.bc_steps:
        p.error(f"--dagger-rounds needs --bc-steps > 0 (the steps of each round), got {a.dagger_rounds}")
    if a.subproc and a.algo == "ppo_lagrangian":
        p.error("--subproc: the Lagrange multiplier is shared in-process; run ppo_lagrangian without it")
    return Args(
        a.timesteps, a.algo, a.cost_budget, a.lambda_lr, a.residual, a.residual_offset, names, a.n_envs,
        a.subproc, a.n_steps,
        a.batch_size, a.learning_rate, a.gamma, a.time_reward,
        a.predictors, a.bc_steps, a.dagger_rounds, a.log_std_init, a.seed, a.eval_every, a.eval_episodes,
        a.out,
        not a.no_progress,
    )  # fmt: skip


def make_env(
    scenarios: tuple[str, ...],
    predictors: bool,
    algo: str = "ppo",
    multiplier: Any = None,
    residual: float = 0.0,
    time_reward: float | None = None,
    residual_offset: float = 0.0,
) -> Any:
    """One training env: a scenario drawn per reset, episode metrics in `info`, optional predictors.

    ``time_reward`` replaces the reward's cost of time (`RewardConfig.time`, per second) when not None.

    Stack (inner to outer): the env, `ScenarioMix` (scenario per reset, episode metrics), the shield
    (``shielded``), the Lagrangian reward (``ppo_lagrangian``, λ from `multiplier`), the prediction wrappers
    (``--predictors``), a filter keeping the keys the policy reads, SB3's `Monitor`.
    """
    import gymnasium as gym

    import crossing_env
    from crossing_env.observation import (
        BASE_KEYS,
        CROSSING_INTENTION_KEY,
        PEDESTRIAN_TRACKS_KEY,
        PREDICTED_PATHS_KEY,
    )
    from crossing_env.safety import EpisodeMetrics

    class ScenarioMix(gym.Wrapper):
        """Draws the scenario of each episode from `names` (seeded by the reset seed, then by episode)."""

        def __init__(self, env: gym.Env, names: tuple[str, ...]) -> None:
            super().__init__(env)
            self.names = names
            self._rng = np.random.default_rng(0)

        def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Any, dict]:
            if seed is not None:
                self._rng = np.random.default_rng(seed)
            name = self.names[int(self._rng.integers(len(self.names)))]
            obs, info = self.env.reset(seed=seed, options={**(options or {}), "scenario": name})
            base = self.env.unwrapped
            self._metrics = EpisodeMetrics(base.scenario, base.config.dt)
            self._return = 0.0
            self._cost = 0.0
            return obs, info

        def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict]:
            obs, reward, terminated, truncated, info = self.env.step(action)
            self._metrics.update(info["ground_truth"])
            self._return += float(reward)
            self._cost += float(info["cost"])
            if terminated or truncated:
                r = self._metrics.result()
                info = {
                    **info,
                    "episode_metrics": {
                        "scenario": r.scenario,
                        "return": self._return,
                        "cost": self._cost,
                        "collision": float(r.collision),
                        "yield_obligations": r.yield_obligations,
                        "yield_violations": r.yield_violations,
                        "delay": r.delay if r.passed_crossing else float("nan"),
                        "duration": r.duration,
                    },
                }
            return obs, reward, terminated, truncated, info

    config = None
    if time_reward is not None:
        from scenarios.config import EnvConfig, RewardConfig

        config = EnvConfig(reward=RewardConfig(time=time_reward))
    env = gym.make(crossing_env.ENV_ID, scenario=scenarios[0], config=config)
    env = ScenarioMix(env, scenarios)
    if algo == "shielded":
        from agents import make_policy
        from agents.shield import ShieldAction

        env = ShieldAction(
            env,
            lambda scenario, dt: make_policy("yielding", scenario=scenario, dt=dt).config,
            residual,
            residual_offset,
        )
    if algo == "ppo_lagrangian":
        from crossing_env.constrained import LagrangianReward

        env = LagrangianReward(env, multiplier)
    # Track ids are labels, not magnitudes (they only grow): an MLP would read noise; a memory needs a
    # recurrent policy or hand-made per-track features.
    keys = [k for k in BASE_KEYS if k != PEDESTRIAN_TRACKS_KEY]
    if predictors:  # the same wrappers, in the same order, as crossing-eval gives a predicting policy
        from rollout import DEFAULT_INTENTION, DEFAULT_PREDICTOR, wrap

        env, _ = wrap(env, DEFAULT_INTENTION, DEFAULT_PREDICTOR)
        keys += [CROSSING_INTENTION_KEY, PREDICTED_PATHS_KEY]
    # Only the keys a policy file records (`agents.mlp`): keys the env may add later do not change its input.
    env = gym.wrappers.FilterObservation(env, keys)
    from stable_baselines3.common.monitor import Monitor

    return Monitor(env)


class EpisodeLog:
    """SB3 callback: one CSV row per finished training episode (return and the safety metrics)."""

    FIELDS = (
        "step", "scenario", "return", "cost", "collision", "obligations", "violations", "delay", "duration",
        "multiplier", "wall_s",
    )  # fmt: skip

    def __init__(
        self, path: Path, multiplier: Any = None, budget: float = 0.0, lambda_lr: float = 0.0
    ) -> None:
        from stable_baselines3.common.callbacks import BaseCallback

        log = self
        self.multiplier = multiplier
        self.costs: list[float] = []
        self.t0 = time.perf_counter()

        class _Callback(BaseCallback):
            def _on_step(self) -> bool:
                for info in self.locals["infos"]:
                    if "episode_metrics" in info:
                        m = info["episode_metrics"]
                        log.costs.append(m["cost"])
                        lam = log.multiplier.value if log.multiplier is not None else 0.0
                        log.writer.writerow(
                            [self.num_timesteps, m["scenario"], m["return"], m["cost"], m["collision"],
                             m["yield_obligations"], m["yield_violations"], m["delay"], m["duration"], lam,
                             round(time.perf_counter() - log.t0, 2)]
                        )  # fmt: skip
                return True

            def _on_rollout_end(self) -> None:
                # Dual ascent on the episodes that ended in this rollout (none ended: λ stays).
                if log.multiplier is not None and log.costs:
                    log.multiplier.update(float(np.mean(log.costs)), budget, lambda_lr)
                    self.logger.record("train/lagrange_multiplier", log.multiplier.value)
                log.costs.clear()

        self.file = path.open("w", newline="", buffering=1)  # line-buffered: readable while training
        self.writer = csv.writer(self.file)
        self.writer.writerow(self.FIELDS)
        self.callback = _Callback()

    def close(self) -> None:
        """Flush and close the CSV."""
        self.file.close()


def _demonstrations(
    env: Any, obs_keys: list[str], steps: int, first_seed: int, actor: Any = None
) -> tuple[dict[str, list[np.ndarray]], list[float]]:
    """`steps` observations labelled with the yielding policy's action.

    The env is driven by the teacher itself (`actor` None) or by `actor(obs)` while the teacher, fed the
    same observations (so its memory follows the episode), labels each step.
    """
    from agents import make_policy

    buf: dict[str, list[np.ndarray]] = {k: [] for k in obs_keys}
    labels: list[float] = []
    episode = 0
    while len(labels) < steps:
        obs, _ = env.reset(seed=first_seed + episode)
        base = env.unwrapped
        teacher = make_policy("yielding", scenario=base.scenario, dt=base.config.dt)
        done = False
        while not done and len(labels) < steps:
            a = np.asarray(teacher(obs), dtype=np.float32).reshape(1)
            for k in obs_keys:
                buf[k].append(obs[k])
            labels.append(float(a[0]))
            act = a if actor is None else np.asarray(actor(obs), dtype=np.float32).reshape(1)
            obs, _, terminated, truncated, _ = env.step(act)
            done = terminated or truncated
        episode += 1
    return buf, labels


def _fit(model: Any, norm: dict[str, np.ndarray], labels: list[float], seed: int, epochs: int) -> float:
    """`epochs` passes of Adam on the MSE between the actor's mean action and the labels."""
    import torch

    target = torch.as_tensor(np.asarray(labels, dtype=np.float32))[:, None]
    policy = model.policy
    opt = torch.optim.Adam(policy.parameters(), lr=1e-3)
    rng = np.random.default_rng(seed)
    n = len(labels)
    loss_value = float("nan")
    for _ in range(epochs):
        for idx in np.array_split(rng.permutation(n), max(1, n // 256)):
            batch = {k: torch.as_tensor(v[idx]) for k, v in norm.items()}
            mean = policy.get_distribution(batch).distribution.mean
            loss = torch.nn.functional.mse_loss(mean, target[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            loss_value = loss.item()
    return loss_value


def dagger_first_seed(seed: int, round_index: int, steps: int) -> int:
    """First episode seed of DAgger round `round_index` of training seed `seed` (`steps` steps a round).

    A round drives at most `steps` episodes, so training seed s takes seeds [s·steps, (s+1)·steps) of its
    round's block of 2³² seeds: no two rounds and no two training seeds (with the same `steps`) meet the
    same episode, and none meets the warm start's demonstrations (seeds below 2³² from ``seed · 100,003``).
    """
    return (round_index + 1) * 2**32 + seed * steps


def behaviour_cloning(model: Any, venv: Any, args: Args, epochs: int = 10) -> float:
    """Fit the actor's mean action to the yielding policy's on `args.bc_steps` demonstration steps, then
    run `args.dagger_rounds` DAgger rounds of as many steps driven by the actor's greedy action.

    The first demonstrations also seed VecNormalize's observation statistics. Returns the final MSE.
    """
    env = make_env(args.scenarios, args.predictors)
    obs_keys = list(venv.observation_space.spaces)
    buf, labels = _demonstrations(env, obs_keys, args.bc_steps, args.seed * 100_003)
    data = {k: np.stack(v) for k, v in buf.items()}
    for k in obs_keys:
        venv.obs_rms[k].update(data[k])
    norm = venv.normalize_obs(data)
    mse = _fit(model, norm, labels, args.seed, epochs)

    def actor(obs: dict[str, np.ndarray]) -> np.ndarray:
        action, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
        return np.clip(action, -1.0, 1.0)

    for r in range(args.dagger_rounds):
        first = dagger_first_seed(args.seed, r, args.bc_steps)
        more, more_labels = _demonstrations(env, obs_keys, args.bc_steps, first, actor)
        fresh = venv.normalize_obs({k: np.stack(v) for k, v in more.items()})
        norm = {k: np.concatenate([norm[k], fresh[k]]) for k in obs_keys}
        labels = labels + more_labels
        mse = _fit(model, norm, labels, args.seed + r + 1, epochs)
        print(f"DAgger round {r + 1}/{args.dagger_rounds}: {len(labels)} labelled steps, MSE {mse:.4f}")
    env.close()
    return mse


def plot_learning_curve(episodes_csv: Path, png: Path, window: int = 200) -> None:
    """Return, collision rate, yield compliance and delay against training steps (moving windows)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with episodes_csv.open() as fh:
        rows = list(csv.DictReader(fh))
    if not rows:  # too short a run to finish an episode: an empty figure that says so
        fig, ax = plt.subplots(figsize=(6, 2))
        ax.text(0.5, 0.5, "no finished training episode yet", ha="center", va="center")
        ax.set_axis_off()
        fig.savefig(png, dpi=90)
        plt.close(fig)
        return
    step = np.array([float(r["step"]) for r in rows])
    ret = np.array([float(r["return"]) for r in rows])
    col = np.array([float(r["collision"]) for r in rows])
    obl = np.array([float(r["obligations"]) for r in rows])
    vio = np.array([float(r["violations"]) for r in rows])
    dur = np.array([float(r["duration"]) for r in rows])
    delay = np.array([float(r["delay"]) for r in rows])
    delay = np.where(np.isnan(delay), dur, delay)  # episodes that never passed count at their duration
    w = max(1, min(window, len(rows) // 5 or 1))
    kernel = np.ones(w)

    def smooth(x: np.ndarray) -> np.ndarray:
        return np.convolve(x, kernel, mode="valid") / w

    s = step[w - 1 :]
    n_obl = np.maximum(np.convolve(obl, kernel, mode="valid"), 1)
    compliance = 1.0 - np.convolve(vio, kernel, mode="valid") / n_obl
    fig, ax = plt.subplots(1, 4, figsize=(16, 3.5))
    for a, y, title in zip(
        ax,
        (smooth(ret), smooth(col), compliance, smooth(delay)),
        (f"return ({w}-episode mean)", "collision rate", "yield compliance", "delay s (unpassed: duration)"),
        strict=True,
    ):
        a.plot(s, y)
        a.set_title(title)
        a.set_xlabel("training steps")
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=90)
    plt.close(fig)


def evaluate(name: str, scenarios: tuple[str, ...], episodes: int, workers: int = 1) -> dict[str, Any]:
    """`crossing-eval`'s episodes (same seeds, same code) for policy spec `name`; metrics plus mean return."""
    from crossing_eval.plugins import policy_spec
    from crossing_eval.runners import run_tasks
    from crossing_eval.scoring import reference_tasks
    from crossing_eval.summary import summarise
    from crossing_eval.tasks import make_tasks

    policy_spec(name)  # fails early with a clear message
    tasks = make_tasks(list(scenarios), [name], episodes, 2024)
    ran = run_tasks(tasks + reference_tasks(tasks), workers, "local", None, show_progress=False)
    records = [r for r in ran if r.task.policy == name]
    summary = summarise(records, [r for r in ran if r.task.policy != name])  # the score's reference
    returns = [r.episode_return for r in records]
    return {"summary": summary, "records": records, "mean_return": float(np.nanmean(returns))}


def main(argv: list[str] | None = None) -> int:
    """Train, save, plot, evaluate; prints the figures."""
    args = parse_args(argv)
    import torch

    torch.set_num_threads(1)
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    from crossing_env.constrained import Multiplier

    args.out.mkdir(parents=True, exist_ok=True)
    multiplier = Multiplier(0.0) if args.algo == "ppo_lagrangian" else None
    fns = [
        lambda: make_env(
            args.scenarios,
            args.predictors,
            args.algo,
            multiplier,
            args.residual,
            args.time_reward,
            args.residual_offset,
        )
        for _ in range(args.n_envs)
    ]
    venv = SubprocVecEnv(fns, start_method="forkserver") if args.subproc else DummyVecEnv(fns)
    venv.seed(args.seed)
    venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=args.gamma)
    model = PPO(
        "MultiInputPolicy",
        venv,
        n_steps=args.n_steps,
        batch_size=min(args.batch_size, args.n_steps * args.n_envs),
        learning_rate=args.learning_rate,
        gamma=args.gamma,
        seed=args.seed,
        device="cpu",
        verbose=0,
        policy_kwargs={"log_std_init": args.log_std_init},
    )
    if args.bc_steps:
        t_bc = time.perf_counter()
        mse = behaviour_cloning(model, venv, args)
        print(f"warm start: imitated the yielding policy on {args.bc_steps} steps (MSE {mse:.4f})"
              f" in {time.perf_counter() - t_bc:.1f} s")  # fmt: skip
    model.set_logger(configure(str(args.out), ["csv"]))
    log = EpisodeLog(args.out / "episodes.csv", multiplier, args.cost_budget, args.lambda_lr)
    from stable_baselines3.common.callbacks import CallbackList, EveryNTimesteps

    shielded = args.algo == "shielded"
    callbacks: list[Any] = [log.callback]
    if args.eval_every:
        callbacks.append(
            EveryNTimesteps(
                args.eval_every,
                _Checkpoint(model, venv, args.out, shielded, args.residual, args.residual_offset),
            )
        )
    t0 = time.perf_counter()
    _save(model, venv, args.out / "step_0.zip", shielded, args.residual, args.residual_offset)
    try:
        model.learn(args.timesteps, callback=CallbackList(callbacks), progress_bar=args.progress)
    except KeyboardInterrupt:  # Ctrl-C stops training early; what was learnt is still saved and evaluated
        print(f"interrupted at {model.num_timesteps} steps", file=sys.stderr)
    train_s = time.perf_counter() - t0
    log.close()
    lam = f", final λ {multiplier.value:.3f}" if multiplier is not None else ""
    print(
        f"trained PPO ({args.algo}) for {model.num_timesteps} steps in {train_s:.1f} s"
        f" ({model.num_timesteps / train_s:.0f} steps/s), seed {args.seed},"
        f" {len(args.scenarios)} scenario(s){lam}"
    )
    _save(model, venv, args.out / "model.zip", shielded, args.residual, args.residual_offset)
    plot_learning_curve(args.out / "episodes.csv", args.out / "learning_curve.png")
    print(
        f"saved {args.out}/model.zip (+ model.vecnormalize.npz, model.policy.npz), episodes.csv,"
        " learning_curve.png"
    )
    venv.close()
    if args.eval_episodes:
        from crossing_eval.summary import format_table

        spec = f"mlp:{args.out / 'model.policy.npz'}"
        ev = evaluate(spec, args.scenarios, args.eval_episodes)
        print(format_table(ev["summary"], [spec]))
        print(f"mean return {ev['mean_return']:.2f} over {len(ev['records'])} episodes")
    return 0


def _save(
    model: Any, venv: Any, path: Path, shielded: bool, residual: float = 0.0, offset: float = 0.0
) -> None:
    """``NAME.zip`` (SB3), ``NAME.vecnormalize.npz`` (statistics), ``NAME.policy.npz`` (`agents.mlp`)."""
    from agents.mlp import export_sb3
    from agents.sb3 import save_stats

    model.save(path)
    save_stats(venv, path.with_suffix(".vecnormalize.npz"))
    export_sb3(
        model,
        venv,
        path.with_suffix(".policy.npz"),
        shielded=shielded,
        residual_scale=residual,
        residual_offset=offset,
    )


def _Checkpoint(
    model: Any, venv: Any, out: Path, shielded: bool, residual: float = 0.0, offset: float = 0.0
) -> Any:
    """Callback: saves ``step_N.zip`` + its statistics + its policy file at every call."""
    from stable_baselines3.common.callbacks import BaseCallback

    class _Save(BaseCallback):
        def _on_step(self) -> bool:
            _save(model, venv, out / f"step_{self.num_timesteps}.zip", shielded, residual, offset)
            return True

    return _Save()


if __name__ == "__main__":
    sys.exit(main())
