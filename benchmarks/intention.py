"""Benchmark the crossing-intention wrappers (QLB, CBM, constant base rate) against ground-truth crossings.

Runs episodes with a fixed seed set, a busy zebra (spawn_rate 20/min) in two worlds (classical "gap"
pedestrians and QLB "qlb" pedestrians), with a simple cautious ego that reads only the observation. Every
(step, present pedestrian slot) is a sample; its label for horizon h is whether that pedestrian, per
``info["ground_truth"]``, is on the carriageway ahead of the ego's rear at some step in [t, t + h]. Slots
are matched to pedestrians with ``env.unwrapped._observer.last_slots`` and the world's pedestrian ids.
Samples whose window runs past the end of the episode are dropped unless already positive.

Prints Brier score (lower is better) and ROC AUC (higher is better) per horizon for QLB, CBM and a constant
equal to the pooled base rate (an in-sample oracle constant: AUC 0.5, Brier p(1-p)), over all samples and
over the "not yet on the road" samples (the ones that need a prediction).

    python -m benchmarks.intention                        # default: 12 seeds per world, about 2 minutes
    python -m benchmarks.intention --episodes 4 --write predictors/INTENTION_RESULTS.md
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from crossing_common.files import write_text_atomic
from crossing_env.env import CrossingEnv
from crossing_env.observation import (
    CROSSING_INTENTION_KEY,
    EGO_KEY,
    PEDESTRIANS_KEY,
    EgoColumn,
    PedestrianColumn,
)
from predictors.intention import ClassicalIntention, QLBIntention
from scenarios import load_scenario
from scenarios.config import BehaviourConfig, PedestrianConfig, ScenarioConfig

HORIZONS = (1.0, 2.0, 4.0)


def cautious_action(obs: dict[str, np.ndarray], target_speed: float = 5.0) -> np.ndarray:
    """A simple ego: cruise at `target_speed`, brake for pedestrians on the road or waiting at the kerb ahead.

    Reads the observation only. Yielding to waiting pedestrians makes crossings in front of the ego common,
    which is what the benchmark needs to score.
    """
    ped = obs[PEDESTRIANS_KEY]
    speed = float(obs[EGO_KEY][EgoColumn.SPEED])
    c = PedestrianColumn
    dx, dy = ped[:, c.DX], ped[:, c.DY]
    near = (ped[:, c.PRESENCE] > 0.5) & (dx > 0.0) & (dx < 25.0) & (np.abs(dy) < 9.0)
    if np.any(near & ((ped[:, c.ON_ROAD] > 0.5) | (ped[:, c.WAITING] > 0.5))):
        return np.array([-0.4 if speed > 0.5 else 0.0], dtype=np.float32)
    return np.array([np.clip((target_speed - speed) / 3.0, -1.0, 1.0)], dtype=np.float32)


def roc_auc(scores: np.ndarray, labels: np.ndarray) -> float:
    """ROC AUC by the rank-sum (Mann-Whitney) statistic, ties counted as one half."""
    pos = labels.astype(bool)
    n_pos, n_neg = int(pos.sum()), int((~pos).sum())
    if n_pos == 0 or n_neg == 0:
        return float("nan")
    order = np.argsort(scores, kind="mergesort")
    ranks = np.empty(scores.size)
    sorted_scores = scores[order]
    # Average ranks over ties.
    _, first, counts = np.unique(sorted_scores, return_index=True, return_counts=True)
    avg = first + (counts - 1) / 2.0 + 1.0
    ranks[order] = np.repeat(avg, counts)
    return float((ranks[pos].sum() - n_pos * (n_pos + 1) / 2.0) / (n_pos * n_neg))


def brier(scores: np.ndarray, labels: np.ndarray) -> float:
    """Mean squared error of probabilities against 0/1 labels."""
    return float(np.mean((scores - labels) ** 2))


def paired_bootstrap(
    q: np.ndarray,
    c: np.ndarray,
    y: np.ndarray,
    episode: np.ndarray,
    episodes: int,
    seed: int,
    draws: int = 2000,
) -> tuple[float, float]:
    """95 % interval of Brier(q) - Brier(c), resampling whole episodes (samples within one are correlated)."""
    diff = np.bincount(episode, weights=(q - y) ** 2 - (c - y) ** 2, minlength=episodes)
    count = np.bincount(episode, minlength=episodes).astype(np.float64)
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, episodes, size=(draws, episodes))
    stats = diff[pick].sum(axis=1) / np.maximum(count[pick].sum(axis=1), 1.0)
    lo, hi = np.percentile(stats, [2.5, 97.5])
    return float(lo), float(hi)


def run_episode(scenario: ScenarioConfig, seed: int) -> dict[str, np.ndarray]:
    """One episode: per (step, present slot) predictions of both variants at every horizon and the labels."""
    env = CrossingEnv(scenario)
    wrappers = {
        (name, h): cls(env, horizon=h)
        for name, cls in (("QLB", QLBIntention), ("CBM", ClassicalIntention))
        for h in HORIZONS
    }
    obs, info = env.reset(seed=seed)
    dt = env.config.dt
    rows: list[tuple[int, int]] = []  # (step, pedestrian id)
    preds: dict[tuple[str, float], list[np.ndarray]] = {key: [] for key in wrappers}
    on_road_obs: list[np.ndarray] = []
    events: dict[int, list[int]] = {}  # id -> steps at which it is on the road ahead of the ego's rear
    step = 0
    while True:
        world = env.unwrapped.world
        slots = env.unwrapped._observer.last_slots
        present = slots >= 0
        ids = world.pedestrians.ids[slots[present]]
        rows.extend((step, int(i)) for i in ids)
        on_road_obs.append(obs[PEDESTRIANS_KEY][present, PedestrianColumn.ON_ROAD] > 0.5)
        for key, wrapper in wrappers.items():
            preds[key].append(wrapper.observation(obs)[CROSSING_INTENTION_KEY][present])
        gt = info["ground_truth"]
        rear = gt.ego_position[0] - gt.ego_size[0] / 2
        hit = gt.on_road & (gt.pedestrian_positions[:, 0] > rear)
        for pid in gt.pedestrian_ids[hit]:
            events.setdefault(int(pid), []).append(step)
        obs, _, terminated, truncated, info = env.step(cautious_action(obs))
        step += 1
        if terminated or truncated:
            break
    last = step - 1
    steps = np.array([r[0] for r in rows])
    pids = np.array([r[1] for r in rows])
    out: dict[str, np.ndarray] = {
        "on_road": np.concatenate(on_road_obs) if on_road_obs else np.zeros(0, bool)
    }
    for h in HORIZONS:
        k = round(h / dt)
        label = np.zeros(steps.size, dtype=bool)
        for j, (s, pid) in enumerate(zip(steps, pids, strict=True)):
            ev = events.get(int(pid))
            if ev:
                e = np.asarray(ev)
                label[j] = bool(np.any((e >= s) & (e <= s + k)))
        keep = label | (steps + k <= last)
        out[f"label_{h}"] = label
        out[f"keep_{h}"] = keep
        for name in ("QLB", "CBM"):
            out[f"{name}_{h}"] = np.concatenate(preds[(name, h)]) if preds[(name, h)] else np.zeros(0)
    env.close()
    return out


def evaluate(episodes: int, seed: int) -> tuple[list[str], dict[str, float]]:
    """Run the seed set in both worlds and format the result table (markdown lines)."""
    base = ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=20.0))
    worlds = {
        "default-20/gap": base,
        "default-20/qlb": replace(
            base, pedestrians=replace(base.pedestrians, behaviour=BehaviourConfig(decision_model="qlb"))
        ),
        "busy_zebra": load_scenario("busy_zebra"),
    }
    lines = [
        "| world | subset | h (s) | samples | positives | Brier QLB | Brier CBM | Brier base "
        "| Brier QLB - CBM [95% CI] | AUC QLB | AUC CBM | AUC base |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    summary: dict[str, float] = {}
    for wname, scenario in worlds.items():
        results = [run_episode(scenario, seed + e) for e in range(episodes)]
        data = {key: np.concatenate([r[key] for r in results]) for key in results[0]}
        episode = np.concatenate([np.full(r["on_road"].size, e) for e, r in enumerate(results)])
        for subset in ("all", "not on road"):
            for h in HORIZONS:
                keep = data[f"keep_{h}"] & (~data["on_road"] if subset == "not on road" else True)
                y = data[f"label_{h}"][keep].astype(np.float64)
                q = data[f"QLB_{h}"][keep].astype(np.float64)
                c = data[f"CBM_{h}"][keep].astype(np.float64)
                rate = float(y.mean()) if y.size else float("nan")
                const = np.full(y.size, rate)
                vals = (brier(q, y), brier(c, y), brier(const, y), roc_auc(q, y), roc_auc(c, y), 0.5)
                lo, hi = paired_bootstrap(q, c, y, episode[keep], episodes, seed)
                for name, v in zip(
                    ("brier_qlb", "brier_cbm", "brier_base", "auc_qlb", "auc_cbm"), vals, strict=False
                ):
                    summary[f"{wname}/{subset}/{h}/{name}"] = v
                lines.append(
                    f"| {wname} | {subset} | {h:g} | {y.size} | {int(y.sum())} | "
                    + " | ".join(f"{v:.4f}" for v in vals[:3])
                    + f" | {vals[0] - vals[1]:+.4f} [{lo:+.4f}, {hi:+.4f}] | "
                    + " | ".join(f"{v:.3f}" for v in vals[3:])
                    + " |"
                )
    return lines, summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=12, help="episodes (seeds) per world")
    parser.add_argument("--seed", type=int, default=1000, help="first seed of the fixed seed set")
    parser.add_argument("--write", type=Path, default=None, help="also write the table as markdown here")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        print(f"error: --episodes must be >= 1, got {args.episodes}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    lines, _ = evaluate(args.episodes, args.seed)
    elapsed = time.perf_counter() - start
    table = "\n".join(lines)
    print(table)
    seeds = f"{args.seed}..{args.seed + args.episodes - 1}"
    print(f"\n{args.episodes} episodes per world, seeds {seeds}, {elapsed:.0f} s")
    if args.write is not None:
        cmd = f"python -m benchmarks.intention --episodes {args.episodes} --seed {args.seed}"
        write_text_atomic(args.write, f"Command: `{cmd}` ({elapsed:.0f} s)\n\n{table}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
