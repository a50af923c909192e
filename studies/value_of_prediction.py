"""Value of prediction v2: each predictor's worth to the car, in delay and safety, against its accuracy.

    python -m studies.value_of_prediction [--episodes 35] [--flip-episodes 10] [--path-episodes 8]

Three measurements, all with `predictive_yielding` (the remembering yielding rules plus release by intent and
conflict checks on predicted paths) on every built-in scenario, paired on `crossing-eval`'s seeds:

1. **The rows** (``--episodes`` per scenario): no prediction; the intention oracle, the learned model, QLB and
   classical; the path oracle (plan-conditioned), CVM and S-CGRU on the first ``--path-episodes`` (the path
   oracle rolls the world forward three times every 0.4 s: one of its episodes in a busy scenario costs
   about 30 s of a core, so 420 of them would take hours on 2 cores).
2. **The accuracy sweep**: the oracles degraded by a known amount (`predictors.degraded`: intent flipped per
   track with probability q, paths with a horizon-growing error sigma), on the first ``--flip-episodes`` and
   ``--path-sweep-episodes`` of the same seeds (probes for the curve, fewer episodes: a path-oracle episode
   costs about ten of the others).
3. **Open-loop accuracy** of every row on the same axes: the Brier score of ``crossing_intent`` against the
   true intent (decided pedestrians, the car driving `yielding` with its predictions off, so every intent
   row meets the same episode), and the ADE of
   ``predicted_paths`` against the true future while the car holds its speed (`constant_speed`, where the
   path oracle is exact), over ``--accuracy-episodes`` per scenario.

Each row's episodes are kept in ``--runs`` (one JSON per row), so an interrupted run resumes where it stopped.
The analysis (`crossing_eval.value_v2`) writes the JSON that `benchmarks.results` renders.
"""

from __future__ import annotations

import argparse
import ast
import functools
import hashlib
import importlib.util
import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

POLICY = "predictive_yielding"
"""The policy of every row: the one that reads intent and paths."""
BASE_SEED = 2024
"""`crossing-eval`'s default base seed: the rows meet the default table's situations."""
INTENT_ROWS: tuple[str, ...] = ("oracle", "learned", "qlb", "classical")
"""Intention wrappers of the rows (with predictor none)."""
PATH_ROWS: tuple[str, ...] = ("oracle", "cvm", "s-cgru")
"""Trajectory predictors of the rows (with intention none)."""
FLIPS: tuple[float, ...] = (0.05, 0.1, 0.2, 0.3, 0.4)
"""Flip probabilities of the degraded intention oracle."""
NOISES: tuple[float, ...] = (0.25, 0.5, 1.0, 1.5)
"""Final-displacement error scales (m, per axis) of the degraded path oracle."""


FINGERPRINT_STEPS = 150
"""Steps of each fingerprint episode (15 s)."""


@functools.cache
def _probe_digest(intention: str, predictor: str) -> str:
    """Hash of short `predictive_yielding` rollouts under one pair of wrappers (`probe_scenarios`)."""
    from crossing_eval.tasks import episode_seed
    from crossing_eval.value_v2 import episode_figures
    from predictors.learned_intent_weights import WEIGHTS_PATH
    from rollout import RolloutSpec, dynamics_digest, run_spec

    digest = hashlib.sha256(f"{intention}/{predictor}".encode())
    if intention in WEIGHTS_INTENTIONS:
        # A short rollout on one zebra may never meet the situation a weights change moves (a new release
        # bound acts on people waiting for a bus), so the file itself is part of the row's fingerprint.
        digest.update(WEIGHTS_PATH.read_bytes())
    if scores_plans(predictor):
        # Likewise a change to how plans are scored may leave every short probe as it was (the wait charge
        # of `agents.plans` did), so the scoring code (its code alone: a reworded docstring moves no episode)
        # and the policy's defaults are part of the stamp.
        from agents.config import PredictiveYieldingConfig

        for path in PLAN_SCORING_FILES:
            digest.update(code_without_docs(path.read_text(encoding="utf-8")).encode())
        digest.update(repr(PredictiveYieldingConfig()).encode())
    for scenario in probe_scenarios(predictor):
        spec = RolloutSpec(scenario=scenario, policy=POLICY, intention=intention, predictor=predictor)
        episode = run_spec(spec, episode_seed(BASE_SEED, scenario, 0), FINGERPRINT_STEPS)
        digest.update(dynamics_digest(episode).encode())
        digest.update(json.dumps(episode_figures(episode.result, scenario), sort_keys=True).encode())
    return digest.hexdigest()


PLAN_SCORING_FILES: tuple[Path, ...] = (Path(str(importlib.util.find_spec("agents.plans").origin)),)
"""Source of the plan scoring, part of the fingerprint of every row whose predictor gives plan forecasts."""


def code_without_docs(source: str) -> str:
    """`source` as code alone: comments, docstrings and layout dropped (`ast.unparse` of the rest).

    The plan-scoring source stamps the path rows, and a row goes stale when its stamp moves; an edit to a
    docstring or a comment changes no episode, so it must not send the study back for half an hour of
    re-measuring (one did, and the committed table failed the registry check). Every statement that is a
    bare string (a docstring, or an attribute's docstring after it) goes.
    """
    tree = ast.parse(source)
    for node in ast.walk(tree):
        for field in ("body", "orelse", "finalbody"):
            block = getattr(node, field, None)
            if not isinstance(block, list) or not block or not isinstance(block[0], ast.stmt):
                continue
            kept = [stmt for stmt in block if not _is_bare_string(stmt)]
            setattr(node, field, kept or [ast.Pass()])
    return ast.unparse(tree)


def _is_bare_string(stmt: ast.stmt) -> bool:
    return (
        isinstance(stmt, ast.Expr)
        and isinstance(stmt.value, ast.Constant)
        and isinstance(stmt.value.value, str)
    )


def scores_plans(predictor: str) -> bool:
    """Whether `predictive_yielding` scores plans under this predictor (the path oracle, exact or noisy)."""
    return predictor == "oracle" or predictor.startswith("oracle-")


def probe_scenarios(predictor: str) -> tuple[str, ...]:
    """Scenarios of a row's probe rollouts: one zebra, and for a path row a pedestrian who reacts to the car.

    On the zebra alone a change to how plans are scored may move nothing (the deferred-conflict charge of
    `agents.plans` left the 0.25 and 0.5 m noise rows' probes identical while it moved their NCAP episodes),
    so a path row also probes ``ncap_cpna``, whose pedestrian steps off by the car's time to arrive.
    """
    return ("zebra_case1",) if predictor == "none" else ("zebra_case1", "ncap_cpna")


WEIGHTS_INTENTIONS: tuple[str, ...] = ("learned", "qlb", "classical")
"""Intention wrappers that read ``predictors/weights/learned_intent.json`` (calibration, release bound)."""


PROBES: tuple[tuple[str, str], ...] = (
    ("oracle", "none"),
    ("learned", "none"),
    ("qlb", "none"),
    ("classical", "none"),
    ("oracle-flip=0.4", "none"),
    ("none", "cvm"),
    ("none", "s-cgru"),
    ("none", "oracle-noise=1.5"),
)
"""Wrapper pairs of the whole study's fingerprint: one of every kind of row. The plain path oracle's
rollout is left out (its noisy version runs it) to keep the check cheap."""


def value_fingerprint() -> str:
    """Hash of short `predictive_yielding` rollouts under each kind of row's wrappers (`PROBES`).

    The rollouts run on the scenarios of `probe_scenarios`.

    The registry's behaviour fingerprint drives `yielding` only; this study goes stale when the predictors,
    the degraded oracles or `predictive_yielding` change what an episode gives.
    """
    digest = hashlib.sha256()
    for intention, predictor in PROBES:
        digest.update(_probe_digest(intention, predictor).encode())
    return digest.hexdigest()[:16]


def row_fingerprint(intention: str, predictor: str) -> str:
    """Hash of the rollouts one row's episodes depend on: the reference's and its own wrappers'.

    A stored row is re-run only when this changes, so a change to one predictor (say, its release bound)
    re-runs that predictor's row and not the others. The plain path oracle is probed through its noisy
    version (`value_fingerprint`), a reference row through its own rollout only.
    """
    probe = (
        ("none", "oracle-noise=1.5")
        if (intention, predictor) == ("none", "oracle")
        else (intention, predictor)
    )
    digest = hashlib.sha256()
    for pair in dict.fromkeys([("none", "none"), probe]):
        digest.update(_probe_digest(*pair).encode())
    return digest.hexdigest()[:16]


def row_names(flips: Sequence[float] = FLIPS, noises: Sequence[float] = NOISES) -> list[tuple[str, str]]:
    """(intention, predictor) of every row, the reference first, the expensive path rows last."""
    rows = [("none", "none")] + [(i, "none") for i in INTENT_ROWS]
    rows += [(f"oracle-flip={q:g}", "none") for q in flips]
    rows += [("none", p) for p in PATH_ROWS]
    rows += [("none", f"oracle-noise={s:g}") for s in noises]
    return rows


def _row_file(runs: Path, intention: str, predictor: str) -> Path:
    return runs / f"{intention}__{predictor}.json".replace("=", "_")


def run_rows(
    rows: Sequence[tuple[str, str]],
    scenarios: Sequence[str],
    episodes: dict[tuple[str, str], int],
    runs: Path,
    workers: int,
    fingerprint: Callable[[str, str], str] = lambda intention, predictor: "",
) -> dict[tuple[str, str], list[dict[str, Any]]]:
    """Episodes of every row (read from ``runs`` where already there).

    Each row is a list of {scenario, episode, seed, result}. A stored row is used only if it was run with
    the same ``fingerprint(intention, predictor)`` (of the behaviour it measures, `row_fingerprint`) and
    scenarios, and has enough episodes.
    """
    from crossing_eval.runners import run_tasks
    from crossing_eval.tasks import make_tasks

    runs.mkdir(parents=True, exist_ok=True)
    out: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for intention, predictor in rows:
        n = episodes[(intention, predictor)]
        path = _row_file(runs, intention, predictor)
        stamp = fingerprint(intention, predictor)
        if path.exists():
            stored = json.loads(path.read_text(encoding="utf-8"))
            same = stored.get("fingerprint") == stamp and stored["scenarios"] == list(scenarios)
            if same and stored["episodes"] >= n:
                out[(intention, predictor)] = [r for r in stored["records"] if r["episode"] < n]
                continue
        tasks = make_tasks(scenarios, [POLICY], n, BASE_SEED, predictor, intention)
        start = time.perf_counter()
        records = run_tasks(tasks, workers=workers, show_progress=False)
        wall = time.perf_counter() - start
        print(f"{intention} / {predictor}: {len(records)} episodes in {wall:.0f} s", file=sys.stderr)
        rows_out = [
            {"scenario": r.task.scenario, "episode": r.task.episode, "seed": r.task.seed, "result": r.result}
            for r in records
        ]
        data = {
            "episodes": n,
            "scenarios": list(scenarios),
            "fingerprint": stamp,
            "wall_seconds": wall,
            "records": rows_out,
        }
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(data) + "\n", encoding="utf-8")
        tmp.replace(path)
        out[(intention, predictor)] = rows_out
    return out


# ---------------------------------------------------------------------------------------------------------
# Open-loop accuracy
# ---------------------------------------------------------------------------------------------------------


def _intent_samples(scenario: str, seed: int, intention: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(predicted intent, true intent, track) of every decided, present pedestrian-step of one episode."""
    from crossing_env.observation import (
        CROSSING_INTENT_KEY,
        PEDESTRIAN_TRACKS_KEY,
        PEDESTRIANS_KEY,
        PedestrianColumn,
    )
    from predictors.oracle import OracleIntention
    from rollout import build_policy, make_env

    env, _ = make_env(scenario, intention=intention)
    truth = OracleIntention(env.unwrapped)
    policy = build_policy("yielding", env, use_predictions=False)  # the same drive whatever it is told
    obs, _ = env.reset(seed=seed)
    policy.reset(seed)
    pred, true, track = [], [], []
    done = False
    while not done:
        t = truth.observation(obs)[CROSSING_INTENT_KEY]
        ok = (obs[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5) & ((t == 0.0) | (t == 1.0))
        pred.append(obs[CROSSING_INTENT_KEY][ok])
        true.append(t[ok])
        track.append(obs[PEDESTRIAN_TRACKS_KEY][ok])
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        done = terminated or truncated
    env.close()
    return np.concatenate(pred), np.concatenate(true), np.concatenate(track).astype(np.int64)


def _path_samples(scenario: str, seed: int, predictor: str) -> tuple[np.ndarray, np.ndarray]:
    """Paths (N, 12, 2) and (track, step) (N, 2) of every present pedestrian-step; `constant_speed` car."""
    from crossing_env.observation import (
        PEDESTRIAN_TRACKS_KEY,
        PEDESTRIANS_KEY,
        PREDICTED_PATHS_KEY,
        PedestrianColumn,
    )
    from predictors.oracle import OracleTrajectory
    from rollout import build_policy, make_env

    if predictor == "oracle":  # the truth: the path oracle without plans (the car holds its speed)
        base, _ = make_env(scenario)
        env: Any = OracleTrajectory(base, plan_accelerations=())
    else:
        env, _ = make_env(scenario, predictor=predictor)
    policy = build_policy("constant_speed", env)
    obs, _ = env.reset(seed=seed)
    policy.reset(seed)
    paths, tracks, steps = [], [], []
    done, step = False, 0
    while not done:
        ok = obs[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5
        paths.append(obs[PREDICTED_PATHS_KEY][ok])
        tracks.append(obs[PEDESTRIAN_TRACKS_KEY][ok])
        steps.append(np.full(int(ok.sum()), step))
        obs, _, terminated, truncated, _ = env.step(policy(obs))
        done, step = terminated or truncated, step + 1
    env.close()
    return np.concatenate(paths), np.stack([np.concatenate(tracks), np.concatenate(steps)], 1)


def _accuracy_job(job: tuple[str, str, int, str]) -> tuple[tuple[str, str, int, str], Any]:
    kind, scenario, seed, name = job
    if kind == "intent":
        return job, _intent_samples(scenario, seed, name)
    return job, _path_samples(scenario, seed, name)


def accuracy(
    scenarios: Sequence[str],
    episodes: int,
    workers: int,
    flips: Sequence[float] = FLIPS,
    noises: Sequence[float] = NOISES,
) -> dict[str, dict[str, dict[str, float]]]:
    """Open-loop Brier (intent rows) and ADE / FDE (path rows) of every row, degraded levels included.

    The degraded levels are computed from the oracle's own samples with the wrappers' draws
    (`predictors.degraded.flip_draw`, `path_error`), so they are exactly what the closed-loop rows saw.
    """
    from concurrent.futures import ProcessPoolExecutor

    from crossing_eval.tasks import episode_seed
    from predictors.degraded import flip_draws, path_errors

    real_intents = [i for i in INTENT_ROWS if i != "oracle"]
    real_paths = [p for p in PATH_ROWS if p != "oracle"]
    jobs = []
    for sc in scenarios:
        for ep in range(episodes):
            seed = episode_seed(BASE_SEED, sc, ep)
            jobs += [("intent", sc, seed, name) for name in ["oracle", *real_intents]]
            jobs += [("path", sc, seed, name) for name in ["oracle", *real_paths]]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        done = dict(pool.map(_accuracy_job, jobs))
    brier: dict[str, list[np.ndarray]] = {}
    errors: dict[str, list[np.ndarray]] = {}
    for sc in scenarios:
        for ep in range(episodes):
            seed = episode_seed(BASE_SEED, sc, ep)
            pred, true, track = done[("intent", sc, seed, "oracle")]
            for name in real_intents:
                p, t, tr = done[("intent", sc, seed, name)]
                if not (np.array_equal(t, true) and np.array_equal(tr, track)):
                    raise RuntimeError(
                        f"{sc} seed {seed}: the {name} run saw other pedestrians than the oracle's"
                    )
                brier.setdefault(name, []).append((p - t) ** 2)
            brier.setdefault("oracle", []).append((pred - true) ** 2)
            draws = flip_draws(seed, track)
            for q in flips:
                flipped = np.where(draws < q, 1.0 - true, true)
                brier.setdefault(f"oracle-flip={q:g}", []).append((flipped - true) ** 2)
            truth, tracks = done[("path", sc, seed, "oracle")]
            for name in real_paths:
                paths, tr = done[("path", sc, seed, name)]
                if not np.array_equal(tr, tracks):
                    raise RuntimeError(
                        f"{sc} seed {seed}: the {name} run saw other pedestrians than the oracle's"
                    )
                errors.setdefault(name, []).append(np.linalg.norm(paths - truth, axis=-1))
            errors.setdefault("oracle", []).append(np.zeros(truth.shape[:2]))
            for s in noises:
                noisy = truth + path_errors(seed, tracks[:, 0], tracks[:, 1], s, truth.shape[1])
                errors.setdefault(f"oracle-noise={s:g}", []).append(np.linalg.norm(noisy - truth, axis=-1))
    out: dict[str, dict[str, dict[str, float]]] = {"intent": {}, "path": {}}
    for name, parts in brier.items():
        sq = np.concatenate(parts)
        out["intent"][name] = {"brier": float(sq.mean()), "samples": int(sq.size)}
    for name, parts in errors.items():
        e = np.concatenate(parts)
        out["path"][name] = {
            "ade": float(e.mean()),
            "fde": float(e[:, -1].mean()),
            "samples": int(e.shape[0]),
        }
    return out


def cached_accuracy(
    scenarios: Sequence[str], episodes: int, workers: int, runs: Path, fingerprint: str = ""
) -> dict[str, dict[str, dict[str, float]]]:
    """`accuracy`, kept in ``runs`` beside the rows (same scenarios and episodes: read, not re-run)."""
    path = runs / "accuracy.json"
    if path.exists():
        stored = json.loads(path.read_text(encoding="utf-8"))
        same = stored.get("fingerprint") == fingerprint and stored["scenarios"] == list(scenarios)
        if same and stored["episodes"] == episodes:
            return stored["accuracy"]
    print("open-loop accuracy ...", file=sys.stderr)
    acc = accuracy(scenarios, episodes, workers)
    runs.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    data = {"scenarios": list(scenarios), "episodes": episodes, "fingerprint": fingerprint, "accuracy": acc}
    tmp.write_text(json.dumps(data) + "\n", encoding="utf-8")
    tmp.replace(path)
    return acc


def main(argv: list[str] | None = None) -> int:
    """Run (or resume) the rows, the sweep and the accuracy, then write the JSON."""
    from crossing_common.files import write_bytes_atomic
    from crossing_eval.value_v2 import analyse, plot_curve
    from scenarios import list_scenarios

    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--episodes", type=int, default=35, help="episodes per scenario of each row")
    parser.add_argument(
        "--flip-episodes", type=int, default=10, help="episodes per scenario of each degraded intent row"
    )
    parser.add_argument(
        "--path-episodes",
        type=int,
        default=35,
        help="episodes per scenario of the path rows (oracle, cvm, s-cgru)",
    )
    parser.add_argument(
        "--path-sweep-episodes", type=int, default=4, help="episodes per scenario of each degraded path row"
    )
    parser.add_argument(
        "--accuracy-episodes", type=int, default=2, help="episodes per scenario of the open-loop accuracy"
    )
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument(
        "--runs", type=Path, default=Path("runs/value_v2"), help="folder of the rows' episodes"
    )
    parser.add_argument("--out", type=Path, default=Path("value_v2.json"), help="the JSON written")
    parser.add_argument(
        "--figure", type=Path, default=Path("docs/value_of_prediction_curve.png"), help="the curve's PNG"
    )
    parser.add_argument(
        "--scenarios", nargs="+", default=None, help="scenarios (default: every built-in one)"
    )
    args = parser.parse_args(argv)
    scenarios = sorted(args.scenarios or list_scenarios())
    rows = row_names()
    episodes = {r: args.episodes for r in rows}
    episodes.update({r: args.flip_episodes for r in rows if r[0].startswith("oracle-flip")})
    episodes.update({r: args.path_episodes for r in rows if r[1] in PATH_ROWS})
    episodes.update({r: args.path_sweep_episodes for r in rows if r[1].startswith("oracle-noise")})
    start = time.perf_counter()
    fingerprint = value_fingerprint()
    records = run_rows(rows, scenarios, episodes, args.runs, args.workers, row_fingerprint)
    acc = cached_accuracy(scenarios, args.accuracy_episodes, args.workers, args.runs, fingerprint)
    settings = {
        "command": (
            f"python -m studies.value_of_prediction --episodes {args.episodes} --flip-episodes"
            f" {args.flip_episodes} --path-episodes {args.path_episodes} --path-sweep-episodes"
            f" {args.path_sweep_episodes} --accuracy-episodes {args.accuracy_episodes}"
        ),
        "workers": args.workers,
        "policy": POLICY,
        "scenarios": scenarios,
        "episodes": args.episodes,
        "flip_episodes": args.flip_episodes,
        "path_episodes": args.path_episodes,
        "path_sweep_episodes": args.path_sweep_episodes,
        "accuracy_episodes": args.accuracy_episodes,
        "seed": BASE_SEED,
        "flips": list(FLIPS),
        "noises": list(NOISES),
    }
    data = analyse(records, acc, settings)
    data["wall_seconds"] = round(time.perf_counter() - start, 1)
    data["rows_wall_seconds"] = round(
        sum(json.loads(_row_file(args.runs, *r).read_text(encoding="utf-8"))["wall_seconds"] for r in rows), 1
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    write_bytes_atomic(args.figure, plot_curve(data))
    print(f"wrote {args.out} and {args.figure}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
