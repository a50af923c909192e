"""Parameter counts and per-batch inference latency of S-CGRU, S-GRU and S-LSTM (the seed paper's Table 2).

Run: ``python benchmarks/predictors.py [--repeats 30] [--rounds 3] [--threads 1] [--rollout-steps 150]
[--fov-sweep --scene eth]``.

Latencies are measured in one process as CPU time of the calling thread (``time.thread_time``, torch and
the wrapper single-threaded), so that other processes on a shared machine inflate them less than wall
time; the models are interleaved round-robin, and ratios are to S-LSTM of the same size measured in the
same rounds ("paired": the median over rounds of the ratio within a round, which cancels load that
drifts between rounds). Two batch sets:

* the ETH test set as one batch (70 windows, 181 pedestrians; a synthetic batch of that shape without the
  data), with freshly initialised models at the paper's size, two controls and the half width;
* the shipped leave-one-out checkpoints on their own test scenes, batched as ``studies.evaluate``
  batches them (whole windows, at most 256 pedestrians), ``--batches`` evenly spaced batches per scene.

``--fov-sweep`` trains a short S-CGRU run per field of view and reports *validation* ADE/FDE (never
test), the analogue of the paper's Table 3.
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

if __name__ in ("__main__", "predictors"):
    # This file shares its name with the ``predictors`` package. Any script run from this folder
    # (``python benchmarks/<name>.py``, this one included) puts the folder first on ``sys.path``, where
    # ``import predictors`` would find this file. So the folder is taken off, and if this file was just
    # imported in the package's place (by a sibling script), the import is handed over to the package.
    _here = Path(__file__).resolve().parent
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _here]
    if __name__ == "predictors":
        del sys.modules["predictors"]
        importlib.import_module("predictors")

import numpy as np
import torch
from torch import nn

from crossing_env.observation import PEDESTRIAN_HISTORY_KEY, PEDESTRIANS_KEY, PedestrianColumn
from predictors.data import SCENES, default_data_root, iterate_batches, load_split, to_batch
from predictors.models import (
    ModelConfig,
    SocialRecurrent,
    count_parameters,
    default_config,
)


def equal_dof_gru_hidden(target: int) -> int:
    """Hidden size of an S-GRU whose parameter count is closest to ``target`` (the real-DoF control)."""
    best = min(
        range(16, 257),
        key=lambda h: abs(count_parameters(SocialRecurrent(ModelConfig("s-gru", h)))[0] - target),
    )
    return best


SHIPPED_KINDS = ("s-lstm", "s-gru", "s-cgru")
HALF = "half width h=64, e=32"
"""Label of the models at the wrapper default's size (``s-cgru_all.pt``)."""


def batch(data: Path) -> tuple[torch.Tensor, torch.Tensor, str]:
    try:
        b = to_batch(load_split(data, "eth", "test"))
        return b.obs, b.seq_start_end, "ETH test (70 windows, 181 peds)"
    except FileNotFoundError:
        g = torch.Generator().manual_seed(0)
        sizes = torch.full((70,), 3)
        sizes[:41] = 2
        ends = torch.cumsum(sizes, 0)
        obs = torch.randn(int(ends[-1]), 8, 2, generator=g).cumsum(1) * 0.3
        return obs, torch.stack([ends - sizes, ends], 1), "synthetic (70 windows, 181 peds)"


def time_models(
    models: dict[str, nn.Module],
    batches: list[tuple[torch.Tensor, torch.Tensor]],
    rounds: int,
    warmup: int = 3,
) -> dict[str, list[float]]:
    """CPU seconds of each model's ``predict`` on each ``(obs, seq_start_end)`` batch, ``rounds`` times.

    Every model runs on a batch before the next batch (interleaved round-robin), after ``warmup``
    untimed runs of each on the first batch; the lists are in round-major, then batch order.
    """
    times: dict[str, list[float]] = {k: [] for k in models}
    with torch.inference_mode():
        for m in models.values():
            for _ in range(warmup):
                m.predict(*batches[0])
        for _ in range(rounds):
            for obs, sse in batches:
                for k, m in models.items():
                    t0 = time.thread_time()
                    m.predict(obs, sse)
                    times[k].append(time.thread_time() - t0)
    return times


def shipped_latency(data: Path, per_scene: int, rounds: int) -> dict[str, dict[str, object]] | None:
    """CPU seconds per batch of the shipped S-LSTM, S-GRU and S-CGRU checkpoints on their own test scenes.

    Batches are whole windows of at most 256 pedestrians, as ``studies.evaluate`` runs them;
    ``per_scene`` evenly spaced batches of each scene, every model on each batch in turn, ``rounds``
    times. ``None`` if a checkpoint or a test split is missing.
    """
    from predictors.checkpoints import WEIGHTS_DIR, load_model

    out: dict[str, dict[str, object]] = {}
    for scene in SCENES:
        paths = {k: WEIGHTS_DIR / f"{k}_{scene}.pt" for k in SHIPPED_KINDS}
        if not all(p.is_file() for p in paths.values()):
            return None
        try:
            every = list(iterate_batches(load_split(data, scene, "test"), 256))
        except FileNotFoundError:
            return None
        pick = np.unique(np.linspace(0, len(every) - 1, per_scene).round().astype(int))
        batches = [every[i] for i in pick]
        models = {k: load_model(p).eval() for k, p in paths.items()}
        times = time_models(models, [(b.obs, b.seq_start_end) for b in batches], rounds, warmup=1)
        peds = float(np.mean([b.obs.shape[0] for b in batches]))
        out[scene] = {"batches": len(batches), "of": len(every), "peds": peds, "times": times}
    return out


def print_shipped_latency(res: dict[str, dict[str, object]], rounds: int, threads: int) -> None:
    """Per scene and over all scenes: mean ms per batch, ratio of means and paired ratio to S-LSTM."""
    print(
        f"\nShipped leave-one-out checkpoints (hidden 128, embedding 64) on their test scenes, most-likely"
        f" rollout, batches of <= 256 pedestrians as in studies.evaluate, {rounds} round(s),"
        f" {threads} thread(s); ms per batch (ratio of means to S-LSTM, paired ratio):"
    )
    pooled: dict[str, list[float]] = {k: [] for k in SHIPPED_KINDS}
    for scene, r in res.items():
        times: dict[str, list[float]] = r["times"]  # type: ignore[assignment]
        cells = []
        for k in SHIPPED_KINDS:
            pooled[k] += times[k]
            mean = statistics.fmean(times[k])
            ratio = mean / statistics.fmean(times["s-lstm"])
            paired = statistics.median(t / b for t, b in zip(times[k], times["s-lstm"], strict=True))
            cells.append(f"{k} {mean * 1e3:6.1f} ({ratio:.2f}, {paired:.2f})")
        print(
            f"  {scene:6s} {r['batches']:2d} of {r['of']:3d} batches, {r['peds']:5.0f} peds: "
            + "  ".join(cells)
        )
    total = {k: sum(v) for k, v in pooled.items()}
    cells = []
    for k in SHIPPED_KINDS:
        paired = statistics.median(t / b for t, b in zip(pooled[k], pooled["s-lstm"], strict=True))
        cells.append(f"{k} {total[k] / total['s-lstm']:.2f} (paired {paired:.2f})")
    print("  all scenes, ratio of total time to S-LSTM: " + "  ".join(cells))


def wrapper_ms(k: int = 16, repeats: int = 200) -> tuple[float, float] | None:
    """Median and minimum CPU ms of one *recompute* of the default wrapper for ``k`` present pedestrians.

    Every call gets a genuinely new history (each pedestrian moved by its own random offset), so the
    wrapper's translation cache never hits: this is the cost of a cache miss.
    """
    from predictors.checkpoints import WEIGHTS_DIR
    from predictors.trajectory_wrapper import TrajectoryPrediction

    if not (WEIGHTS_DIR / "s-cgru_all.pt").is_file():
        return None
    import gymnasium as gym
    from gymnasium import spaces

    class _Env(gym.Env):
        observation_space = spaces.Dict(
            {
                PEDESTRIANS_KEY: spaces.Box(-1e3, 1e3, (k, 4), np.float32),
                PEDESTRIAN_HISTORY_KEY: spaces.Box(-1e3, 1e3, (k, 8, 2), np.float32),
            }
        )
        action_space = spaces.Discrete(1)

    rng = np.random.default_rng(0)
    hist = rng.uniform(-10, 10, (k, 1, 2)) + np.arange(8)[None, :, None] * rng.uniform(-0.5, 0.5, (k, 1, 2))
    obs = [
        {
            PEDESTRIANS_KEY: np.ones((k, 4), np.float32),
            PEDESTRIAN_HISTORY_KEY: (hist + rng.normal(size=(k, 1, 2))).astype(np.float32),
        }
        for _ in range(repeats + 20)
    ]
    w = TrajectoryPrediction(_Env())
    for o in obs[:20]:
        w.observation(o)
    ts = []
    for o in obs[20:]:
        t0 = time.thread_time()
        w.observation(o)
        ts.append(time.thread_time() - t0)
    assert w.cache_hits == 0
    return statistics.median(ts) * 1e3, min(ts) * 1e3


def crowd_scenario(count: int, seed: int) -> object:
    """``count`` pedestrians on both sidewalks 0-80 m ahead of the ego's start (it sees them all)."""
    from scenarios.config import (
        PedestrianConfig,
        PedestrianSpawn,
        RoadConfig,
        ScenarioConfig,
        TrafficConfig,
    )

    rng = np.random.default_rng(seed)
    spawns = tuple(
        PedestrianSpawn(x=float(x), side="south" if i % 2 == 0 else "north", crosses=bool(i % 3 != 0))
        for i, x in enumerate(rng.uniform(30.0, 110.0, size=count))
    )
    return ScenarioConfig(
        road=RoadConfig(length=400.0),
        pedestrians=PedestrianConfig(spawns=spawns, spawn_rate=0.0, max_pedestrians=count),
        traffic=TrafficConfig(flow_per_lane=300.0),
    )


def wrapper_rollout(count: int, episodes: int = 2, steps: int = 150) -> dict[str, float] | None:
    """The default wrapper as users meet it: its added CPU time per env step over real Crossing-v0 rollouts.

    A crowd of ``count`` pedestrians near the ego (16 fills the 16 observation slots exactly; more make
    the slot set change as the ego passes them); the ego drives slowly (action -0.2). Every
    ``observation()`` call of the wrapper (the whole added work, reset included) is timed with
    ``time.thread_time`` and classed as a cache hit or a recompute by the wrapper's counters.
    """
    from predictors.checkpoints import WEIGHTS_DIR
    from predictors.trajectory_wrapper import TrajectoryPrediction

    if not (WEIGHTS_DIR / "s-cgru_all.pt").is_file():
        return None
    import gymnasium as gym

    import crossing_env  # noqa: F401  (registers Crossing-v0)

    warm = TrajectoryPrediction(gym.make("crossing_env/Crossing-v0", scenario=crowd_scenario(count, 0)))
    warm.reset(seed=0)
    warm.step(np.array([-0.2], np.float32))  # untimed: compiles (or loads) the numba kernels
    warm.close()
    hit_t: list[float] = []
    miss_t: list[float] = []
    present: list[int] = []
    for ep in range(episodes):
        env = TrajectoryPrediction(gym.make("crossing_env/Crossing-v0", scenario=crowd_scenario(count, ep)))
        observe = env.observation

        def timed(o: dict[str, np.ndarray], observe=observe, env=env) -> dict[str, np.ndarray]:
            misses = env.cache_misses
            t0 = time.thread_time()
            out = observe(o)
            dt = time.thread_time() - t0
            (miss_t if env.cache_misses > misses else hit_t).append(dt)
            present.append(int((o[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5).sum()))
            return out

        env.observation = timed  # type: ignore[method-assign]
        env.reset(seed=ep)
        action = np.array([-0.2], np.float32)
        for _ in range(steps):
            *_, term, trunc, _ = env.step(action)
            if term or trunc:
                env.reset()
        env.close()
    all_t = np.array(hit_t + miss_t) * 1e3
    return {
        "calls": float(all_t.size),
        "mean": float(all_t.mean()),
        "median": float(np.median(all_t)),
        "miss_mean": float(np.mean(miss_t) * 1e3) if miss_t else float("nan"),
        "miss_median": float(np.median(miss_t) * 1e3) if miss_t else float("nan"),
        "hit_mean": float(np.mean(hit_t) * 1e3) if hit_t else float("nan"),
        "hit_rate": len(hit_t) / all_t.size,
        "present_16": float(np.mean(np.array(present) == 16)),
        "present_mean": float(np.mean(present)),
    }


def fov_sweep(scene: str, fovs: list[float], minutes: float, data: Path) -> None:
    from predictors.checkpoints import checkpoint_meta
    from predictors.train import TrainConfig, train

    print(f"\nFoV sweep on {scene} (validation split, {minutes} min per run, TrainConfig defaults)")
    for fov in fovs:
        out = Path(tempfile.gettempdir()) / f"fov_{scene}_{int(fov)}.pt"
        cfg = TrainConfig(
            model="s-cgru",
            scene=scene,
            epochs=100,
            max_minutes=minutes,
            fov_deg=fov,
            data=str(data),
            out=str(out),
        )
        train(cfg)
        meta = checkpoint_meta(out)
        print(
            f"fov {fov:5.0f} deg: val ADE/FDE {meta['val_ade']:.3f}/{meta['val_fde']:.3f}"
            f" (epochs {meta['epochs_run']})"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=30)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--rounds", type=int, default=3, help="rounds over the shipped checkpoints' test batches")
    p.add_argument(
        "--batches", type=int, default=12, help="test batches per scene for the shipped checkpoints"
    )
    p.add_argument("--data", default="")
    p.add_argument("--fov-sweep", action="store_true")
    p.add_argument("--scene", default="eth")
    p.add_argument("--sweep-minutes", type=float, default=2.0)
    p.add_argument(
        "--rollout-steps", type=int, default=150, help="env steps per wrapper rollout episode (0: skip)"
    )
    a = p.parse_args()
    if a.batches < 1 or a.rounds < 0 or a.repeats < 1:
        p.error("--batches and --repeats must be >= 1 and --rounds >= 0")
    torch.set_num_threads(a.threads)
    torch.manual_seed(0)
    data = Path(a.data) if a.data else default_data_root()

    cg = SocialRecurrent(default_config("s-cgru"))
    models: dict[str, nn.Module] = {
        "s-lstm": SocialRecurrent(default_config("s-lstm")),
        "s-gru": SocialRecurrent(default_config("s-gru")),
        "s-cgru": cg,
    }
    h_eq = equal_dof_gru_hidden(count_parameters(cg)[1])
    models[f"s-gru (h={h_eq}, equal DoF)"] = SocialRecurrent(ModelConfig("s-gru", h_eq))
    models["s-cgru (128 complex units)"] = SocialRecurrent(replace(default_config("s-cgru"), hidden_size=256))
    for k in SHIPPED_KINDS:  # the size of the wrapper's default model, s-cgru_all.pt
        models[f"{k} ({HALF})"] = SocialRecurrent(
            replace(default_config(k), hidden_size=64, embed_size=32, cv_residual=True)
        )
    print("Parameters (numel / real degrees of freedom):")
    for k, m in models.items():
        n, d = count_parameters(m)
        print(f"  {k:32s} {n:9,d} / {d:9,d}")
    native = nn.GRUCell(128, 128, dtype=torch.cfloat)
    n, d = count_parameters(native)
    print(f"  {'native complex GRUCell(128)':32s} {n:9,d} / {d:9,d}  (cell only, for reference)")

    obs, sse, label = batch(data)
    times = time_models(models, [(obs, sse)], a.repeats)
    print(
        f"\nInference CPU time per batch, most-likely 12-step rollout, {label}, freshly initialised models,"
        f" {a.threads} thread(s),"
        f" {a.repeats} repeats (ratios to S-LSTM of the same size; 'paired': median over rounds of the"
        f" ratio within a round, which cancels load that drifts between rounds):"
    )
    for k, v in times.items():
        base = times[f"s-lstm ({HALF})"] if HALF in k else times["s-lstm"]
        med, low = statistics.median(v) * 1e3, min(v) * 1e3
        paired = statistics.median(t / b for t, b in zip(v, base, strict=True))
        print(
            f"  {k:32s} median {med:7.2f} ms (ratio {med / (statistics.median(base) * 1e3):.2f})"
            f"   min {low:7.2f} ms (ratio {low / (min(base) * 1e3):.2f})   paired ratio {paired:.2f}"
        )
    shipped = shipped_latency(data, a.batches, a.rounds) if a.rounds else None
    if shipped is not None:
        print_shipped_latency(shipped, a.rounds, a.threads)
    elif a.rounds:
        print(
            f"\nShipped checkpoints not timed: a checkpoint in predictors/weights or a test split in {data}"
            " is missing"
        )
    wm = wrapper_ms()
    if wm is not None:
        print(
            f"\nTrajectoryPrediction wrapper, K=16 present pedestrians, default weights, a new history every"
            f" call (recompute): median {wm[0]:.2f} ms, min {wm[1]:.2f} ms"
        )
    for count in (16, 24) if a.rollout_steps else ():
        r = wrapper_rollout(count, steps=a.rollout_steps)
        if r is None:
            break
        print(
            f"TrajectoryPrediction wrapper on Crossing-v0, {count}-pedestrian crowd ({r['calls']:.0f} calls;"
            f" 16 slots full in {100 * r['present_16']:.0f}% of steps, mean {r['present_mean']:.1f} present):"
            f"\n  added time per env step mean {r['mean']:.2f} ms, median {r['median']:.2f} ms;"
            f" cache hit rate {100 * r['hit_rate']:.0f}%; per recompute mean {r['miss_mean']:.2f} ms,"
            f" median {r['miss_median']:.2f} ms; per hit mean {r['hit_mean']:.3f} ms"
        )
    if a.fov_sweep:
        fov_sweep(a.scene, [60.0, 85.0, 120.0, 180.0, 360.0], a.sweep_minutes, data)


if __name__ == "__main__":
    main()
