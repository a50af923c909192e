"""Choose each intent predictor's release risk bound in closed loop, on selection episodes.

    python -m studies.release_bounds   # after `python -m studies.train_learned_intent`

Why closed loop: the training's open-loop bound (the largest threshold at which at most 1 % of the people
who cross are *ever*, at a single step, released while they stand at the kerb) is a proxy that the issue's
own criterion does not need, and it is far stricter: one low sample anywhere in a crosser's wait counts, while
the car releases per step and yields again to anyone who steps towards the road. The criterion asked for is
the driving one: a bound such that yield compliance stays at or above `MIN_COMPLIANCE`.

How: for each model (learned, QLB, classical), `predictive_yielding` drives every built-in scenario under
that intention wrapper with its published ``crossing_intent_bound`` replaced by each bound of `GRID`, in
ascending order, on `EPISODES` episodes per scenario seeded from `SELECTION_SEED` (``crossing-eval`` and the
value study use 2024, so they never meet these episodes). A bound passes with no collision and yield
compliance ≥ `MIN_COMPLIANCE` over the episodes; the kept bound is the last that passes before the first that
fails (compliance falls as the bound rises, so the sweep stops there), or the open-loop bound if the first
grid value fails.

Then each kept bound is **confirmed** on `CONFIRM_EPISODES` further episodes per scenario (base seed
`CONFIRM_SEED`, also never evaluated) and stepped down the grid until it passes there too (never below the
open-loop bound). Ten episodes per scenario do not see every rare release: the first version of this study
had no confirmation and kept QLB's 0.10, which passed 181 of 181 obligations in the sweep and then broke
compliance on the evaluation episodes of the value study (0.983; `children_running` 0.922).

The chosen thresholds, the open-loop ones, the sweep and the confirmations are written into the release
section of ``predictors/weights/learned_intent.json`` (and its sha256 manifest); nothing else in the file
changes. A stored sweep is reused when the model (heads and calibration) and the settings are unchanged
(``--fresh`` re-runs it).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

MODELS: tuple[str, ...] = ("learned", "qlb", "classical")
"""Intent predictors whose bound is chosen (the intention wrappers of the same names)."""
GRID: tuple[float, ...] = tuple(round(0.05 * i, 2) for i in range(1, 17))
"""Candidate bounds, ascending: 0.05 .. 0.80."""
EPISODES = 10
"""Selection episodes per scenario and bound."""
SELECTION_SEED = 777
"""Base seed of the selection episodes (``crossing-eval`` defaults to 2024)."""
CONFIRM_EPISODES = 30
"""Confirmation episodes per scenario of a kept bound."""
CONFIRM_SEED = 778
"""Base seed of the confirmation episodes."""
MIN_COMPLIANCE = 0.99
"""Yield compliance a bound must keep on the selection episodes (the issue's target)."""
POLICY = "predictive_yielding"
"""The policy that reads the bound (`agents.predictive`)."""


class FixedBound(gym.ObservationWrapper):
    """Replaces the intent wrapper's published release bound by `bound` (the sweep's only change)."""

    def __init__(self, env: gym.Env, bound: float) -> None:
        super().__init__(env)
        self.bound = float(bound)

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        """The observation with ``crossing_intent_bound`` set to `bound`."""
        from predictors.learned_intent_weights import CROSSING_INTENT_BOUND_KEY

        out = dict(observation)
        out[CROSSING_INTENT_BOUND_KEY] = np.array([self.bound], dtype=np.float32)
        return out


_BUILT: dict[tuple[str, str], Any] = {}


def _episode(job: tuple[str, str, float, int, int]) -> dict[str, Any]:
    """One episode: (model, scenario, bound, episode index, base seed) → its scored result."""
    from crossing_eval.tasks import episode_seed
    from rollout import RolloutSpec, build, run_episode

    model, scenario, bound, index, base_seed = job
    key = (model, scenario)
    if key not in _BUILT:
        _BUILT[key] = build(RolloutSpec(scenario=scenario, policy=POLICY, intention=model, predictor="none"))
    run = _BUILT[key]
    episode = run_episode(FixedBound(run.env, bound), episode_seed(base_seed, scenario, index), run.policy)
    r = episode.result
    return {
        "scenario": scenario,
        "episode": index,
        "collision": bool(r["collision"]),
        "compliant": int(r["yield_compliant"]),
        "obligations": int(r["yield_obligations"]),
        "duration": float(r["duration"]),
    }


def summarise(bound: float, results: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """One grid point: episodes, collisions, compliance and mean episode duration."""
    compliant = sum(r["compliant"] for r in results)
    obligations = sum(r["obligations"] for r in results)
    return {
        "bound": bound,
        "episodes": len(results),
        "collisions": sum(r["collision"] for r in results),
        "compliant": compliant,
        "obligations": obligations,
        "compliance": compliant / obligations if obligations else 1.0,
        # No episode, no mean (NaN without numpy's empty-slice warning).
        "mean_duration": float(np.mean([r["duration"] for r in results])) if results else float("nan"),
    }


def passes(point: dict[str, Any], min_compliance: float = MIN_COMPLIANCE) -> bool:
    """A bound passes with no collision and compliance at or above `min_compliance`."""
    return point["collisions"] == 0 and point["compliance"] >= min_compliance


def choose(points: Sequence[dict[str, Any]], fallback: float) -> float:
    """The last passing bound before the first failing one (`points` ascending), else `fallback`."""
    chosen = fallback
    for point in points:
        if not passes(point):
            break
        chosen = max(chosen, point["bound"])
    return chosen


def sweep(
    model: str,
    scenarios: Sequence[str],
    episodes: int,
    pool: ProcessPoolExecutor,
    grid: Sequence[float] = GRID,
) -> list[dict[str, Any]]:
    """The grid points of `model`, ascending, up to and including the first that fails."""
    points = []
    for bound in grid:
        point = evaluate(model, bound, scenarios, episodes, SELECTION_SEED, pool)
        points.append(point)
        if not passes(point):
            break
    return points


def evaluate(
    model: str,
    bound: float,
    scenarios: Sequence[str],
    episodes: int,
    base_seed: int,
    pool: ProcessPoolExecutor,
) -> dict[str, Any]:
    """One grid point: `episodes` per scenario seeded from `base_seed` at `bound`."""
    jobs = [(model, sc, bound, i, base_seed) for sc in scenarios for i in range(episodes)]
    start = time.perf_counter()
    point = summarise(bound, list(pool.map(_episode, jobs)))
    print(
        f"{model} bound {bound:.2f} (seed {base_seed}): {point['collisions']} collisions, compliance"
        f" {point['compliant']}/{point['obligations']}, mean duration {point['mean_duration']:.2f} s"
        f" ({time.perf_counter() - start:.0f} s)",
        file=sys.stderr,
    )
    return point


def confirm(
    model: str,
    chosen: float,
    floor: float,
    scenarios: Sequence[str],
    episodes: int,
    pool: ProcessPoolExecutor,
    grid: Sequence[float] = GRID,
) -> tuple[float, list[dict[str, Any]]]:
    """The largest bound at or below `chosen` that also passes on the confirmation episodes.

    Steps down `grid` from `chosen`; `floor` (the open-loop bound) is kept unconfirmed if nothing above it
    passes. Returns the bound and every confirmation point run.
    """
    points: list[dict[str, Any]] = []
    for bound in sorted((b for b in grid if floor < b <= chosen), reverse=True):
        point = evaluate(model, bound, scenarios, episodes, CONFIRM_SEED, pool)
        points.append(point)
        if passes(point):
            return bound, points
    return floor, points


def model_digest(weights: dict[str, Any]) -> str:
    """sha256 of everything in the weights but the release section and the training notes."""
    import hashlib

    kept = {k: v for k, v in weights.items() if k not in ("release", "training")}
    return hashlib.sha256(json.dumps(kept, sort_keys=True).encode()).hexdigest()


def main(argv: Sequence[str] | None = None) -> int:
    """Sweep every model and write the chosen bounds into the shipped weights."""
    from crossing_eval.runners import pool_start_method
    from predictors.learned_intent_train import write_weights
    from predictors.learned_intent_weights import MANIFEST_PATH, WEIGHTS_PATH, read_weights
    from scenarios import list_scenarios

    parser = argparse.ArgumentParser(
        prog="python -m studies.release_bounds",
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--episodes", type=int, default=EPISODES, help="selection episodes per scenario")
    parser.add_argument(
        "--confirm-episodes", type=int, default=CONFIRM_EPISODES, help="confirmation episodes per scenario"
    )
    parser.add_argument("--fresh", action="store_true", help="re-run the sweep even if the stored one fits")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument("--weights", type=Path, default=WEIGHTS_PATH, help="weights file to update")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.confirm_episodes < 1:
        parser.error(
            f"--episodes and --confirm-episodes must be >= 1, got {args.episodes}, {args.confirm_episodes}"
        )
    weights = read_weights(args.weights, args.weights.with_name(MANIFEST_PATH.name))
    scenarios = sorted(list_scenarios())
    start = time.perf_counter()
    release = weights["release"]
    settings = {
        "policy": POLICY,
        "seed": SELECTION_SEED,
        "episodes_per_scenario": args.episodes,
        "scenarios": scenarios,
        "min_compliance": MIN_COMPLIANCE,
        "grid": list(GRID),
        "model_sha256": model_digest(weights),
    }
    previous = release.get("closed_loop") or {}
    reuse = not args.fresh and all(previous.get(k) == v for k, v in settings.items())
    sweeps: dict[str, Any] = dict(previous["sweeps"]) if reuse else {}
    confirmations: dict[str, Any] = {}
    context = multiprocessing.get_context(pool_start_method())
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=context) as pool:
        for model in MODELS:
            entry = release["models"][model]
            open_loop = float(entry.get("open_loop_threshold", entry["threshold"]))
            if model not in sweeps:
                sweeps[model] = sweep(model, scenarios, args.episodes, pool)
            else:
                print(f"{model}: sweep reused from the weights file", file=sys.stderr)
            kept = choose(sweeps[model], open_loop)
            bound, confirmations[model] = confirm(
                model, kept, open_loop, scenarios, args.confirm_episodes, pool
            )
            entry["open_loop_threshold"] = open_loop
            entry["threshold"] = bound
    release["closed_loop"] = {
        **settings,
        "command": (
            f"python -m studies.release_bounds --episodes {args.episodes}"
            f" --confirm-episodes {args.confirm_episodes}"
        ),
        "sweeps": sweeps,
        "confirm_seed": CONFIRM_SEED,
        "confirm_episodes_per_scenario": args.confirm_episodes,
        "confirmations": confirmations,
        "sweeps_reused": reuse,
        "wall_seconds": round(time.perf_counter() - start, 1),
    }
    digest = write_weights(weights, args.weights)
    chosen = {m: release["models"][m]["threshold"] for m in MODELS}
    print(f"wrote {args.weights.name} (sha256 {digest[:12]}…); release bounds {json.dumps(chosen)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
