"""Fit the learned intent model, the QLB / classical intent calibration and the release risk bound.

    python -m studies.train_learned_intent          # 8 training seeds per world, a few minutes on 2 cores

Data: episodes of `TRAIN_WORLDS` (the intention benchmark's three worlds and the zebra scenarios) on seeds
``seed .. seed + episodes - 1`` (default 0..7), disjoint from the benchmark's evaluation seeds
(`EVAL_SEEDS`, refused here) and, being small integers, from the hashed 32-bit episode seeds of
``crossing-eval``. The ego is `cautious_action` (observation only; it stops for anyone waiting at the kerb,
so a pedestrian's label says what it does when the car gives way). Each (step, present pedestrian slot) is
a sample (`collect_episode`); its labels come from the world's ground truth.

Fitted, all deterministically (L-BFGS from zeros on fixed data; no random draws):

- one L2-regularised logistic-regression head per target on `predictors.learned_intent.FEATURES`: on the
  road ahead of the ego's rear within 1, 2, 4 s, and on the road anywhere within `INTENT_HORIZON` (intent);
- Platt coefficients for the raw QLB and classical intent (their model over `INTENT_HORIZON`);
- the rule baseline's rates (positive rate off the road, at the kerb facing the road, on the road);
- the **open-loop release bound** of each model (learned, QLB, classical): the largest threshold on a grid
  such that, on the training seeds, at most `RELEASE_MISS` of the pedestrians who do cross within
  `INTENT_HORIZON` are ever released while they stand by the kerb at a zebra ahead of the car (the ``min`` of
  the model's calibrated ``crossing_intent`` over their candidate samples at or below it). It is written as
  each model's ``threshold``; ``python -m studies.release_bounds`` then chooses the shipped bound in closed
  loop (compliance kept at 0.99 by driving on selection episodes) and keeps this one as
  ``open_loop_threshold``. Each wrapper publishes its bound in the observation (``crossing_intent_bound``)
  and `agents.predictive` releases only below it.

Writes ``predictors/weights/learned_intent.json`` and its sha256 manifest.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize

from crossing_common.files import write_text_atomic
from crossing_env.env import CrossingEnv
from crossing_env.observation import (
    CROSSING_INTENT_KEY,
    EGO_KEY,
    PEDESTRIANS_KEY,
    EgoColumn,
    PedestrianColumn,
)
from predictors.forecast import scene_from_env
from predictors.intention import (
    INTENT_HORIZON,
    IntentionConfig,
    crossing_intention,
    look_rate_table,
)
from predictors.learned_intent import FEATURES, HEADS, intent_features, predict
from predictors.learned_intent_weights import FORMAT, MANIFEST_PATH, WEIGHTS_PATH, platt, sha256_bytes
from predictors.oracle import OracleIntention
from scenarios import load_scenario
from scenarios.config import BehaviourConfig, PedestrianConfig, ScenarioConfig

HORIZONS = (1.0, 2.0, 4.0)
"""Horizons (s) of the near-term ``crossing_intention`` heads."""
EVAL_SEEDS = range(1000, 1100)
"""Seeds reserved for evaluation (`benchmarks.intention` uses 1000 onwards): never trained on."""
ZEBRA_SCENARIOS = (
    "busy_zebra",
    "zebra_case1",
    "bus_stop_zebra",
    "night_distracted",
    "children_running",
    "four_lane_arterial",
    "occluded_parked_car",
)
"""Built-in scenarios with a zebra (where a release matters)."""
L2 = 1e-4
"""L2 penalty on the standardised coefficients (per sample, on the mean log loss)."""
RELEASE_MISS = 0.01
"""Largest share of crossing pedestrians the release may wrongly release on the training seeds."""
RELEASE_GRID = tuple(round(0.005 * i, 3) for i in range(1, 101))
"""Candidate release thresholds."""
KERB_DISTANCE = 2.0
"""A release candidate stands this close (m) to the kerb (the yielding policy's waiting rule)."""
KERB_MARGIN = 1.5
"""... within the crossing's extent ± this (m) along the road."""
LEAVING_SPEED = 0.5
"""... and is not walking away from the road faster than this (m/s)."""
STEPPING_SPEED = 0.3
"""... nor stepping towards it faster than this (m/s), which the policy never releases."""


def benchmark_worlds() -> dict[str, ScenarioConfig]:
    """The intention benchmark's worlds: a busy default road with gap / QLB pedestrians and busy_zebra."""
    base = ScenarioConfig(pedestrians=PedestrianConfig(spawn_rate=20.0))
    qlb = replace(base.pedestrians, behaviour=BehaviourConfig(decision_model="qlb"))
    return {
        "default-20/gap": base,
        "default-20/qlb": replace(base, pedestrians=qlb),
        "busy_zebra": load_scenario("busy_zebra"),
    }


def train_worlds() -> dict[str, ScenarioConfig]:
    """The training worlds: the benchmark's and the other zebra scenarios."""
    worlds = benchmark_worlds()
    for name in ZEBRA_SCENARIOS:
        worlds.setdefault(name, load_scenario(name))
    return worlds


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


def _labels(steps: np.ndarray, pids: np.ndarray, events: dict[int, list[int]], k: int) -> np.ndarray:
    """Whether each (step, id) has an event in [step, step + k]."""
    label = np.zeros(steps.size, dtype=bool)
    for j, (s, pid) in enumerate(zip(steps, pids, strict=True)):
        ev = events.get(int(pid))
        if ev:
            i = np.searchsorted(ev, s)
            label[j] = i < len(ev) and ev[i] <= s + k
    return label


def collect_episode(
    scenario: ScenarioConfig, seed: int, max_steps: int | None = None
) -> dict[str, np.ndarray]:
    """One episode with `cautious_action`: per (step, present slot) features, model outputs and labels.

    Keys: ``step``, ``pid``, ``features`` (N, F), ``on_road`` (observation flag), ``candidate`` (stands by
    the kerb at a zebra ahead, as the release rule sees it), ``oracle`` (the oracle's intent), ``qlb_<h>``
    / ``cbm_<h>`` (near-term estimates), ``qlb_intent_raw`` / ``cbm_intent_raw`` (uncalibrated intent),
    ``label_<h>`` / ``keep_<h>`` for h in 1, 2, 4 and ``intent``. Samples whose window runs past the end of
    the episode are not kept unless already positive.
    """
    env = CrossingEnv(scenario)
    oracle = OracleIntention(env)
    obs, info = env.reset(seed=seed)
    road_map = scene_from_env(env)
    config = IntentionConfig()
    rates = {
        v: (look_rate_table(v, config), look_rate_table(v, config, config.red_light_prior))
        for v in ("qlb", "cbm")
    }
    dt = env.config.dt
    cols: dict[str, list[np.ndarray]] = {}

    def add(key: str, value: np.ndarray) -> None:
        cols.setdefault(key, []).append(value)

    ahead_events: dict[int, list[int]] = {}
    road_events: dict[int, list[int]] = {}
    step = 0
    while True:
        world = env.unwrapped.world
        slots = env.unwrapped._observer.last_slots
        present = slots >= 0
        add("step", np.full(int(present.sum()), step))
        add("pid", world.pedestrians.ids[slots[present]].astype(np.int64))
        feats = intent_features(obs, road_map)
        add("features", feats[present])
        add("on_road", obs[PEDESTRIANS_KEY][present, PedestrianColumn.ON_ROAD] > 0.5)
        add("oracle", oracle.observation(obs)[CROSSING_INTENT_KEY][present])
        f = {name: feats[present, i] for i, name in enumerate(FEATURES)}
        ego = obs[EGO_KEY]
        candidate = (
            (f["kerb_offset"] > 0.0)
            & (f["kerb_offset"] <= KERB_DISTANCE)
            & (f["towards_road"] > -LEAVING_SPEED)
            & (f["towards_road"] <= STEPPING_SPEED)
            & (f["crossing_distance"] <= KERB_MARGIN)
            & (f["zebra"] > 0.5)
            & (ego[EgoColumn.DISTANCE_PAST_CROSSING] < 0.0)
        )
        add("candidate", candidate)
        for variant, (rate, red) in rates.items():
            for h in HORIZONS:
                add(f"{variant}_{h:g}", crossing_intention(obs, h, road_map, config, rate, red)[present])
            raw = crossing_intention(obs, INTENT_HORIZON, road_map, config, rate, red, ahead_only=False)
            add(f"{variant}_intent_raw", raw[present])
        gt = info["ground_truth"]
        rear = gt.ego_position[0] - gt.ego_size[0] / 2
        for pid in gt.pedestrian_ids[gt.on_road & (gt.pedestrian_positions[:, 0] > rear)]:
            ahead_events.setdefault(int(pid), []).append(step)
        for pid in gt.pedestrian_ids[gt.on_road]:
            road_events.setdefault(int(pid), []).append(step)
        obs, _, terminated, truncated, info = env.step(cautious_action(obs))
        step += 1
        if terminated or truncated or (max_steps is not None and step >= max_steps):
            break
    env.close()
    last = step - 1
    out = {key: np.concatenate(value) for key, value in cols.items()}
    out["features"] = out["features"].reshape(-1, len(FEATURES))
    steps, pids = out["step"], out["pid"]
    for key, horizon, events in (
        *((f"{h:g}", h, ahead_events) for h in HORIZONS),
        ("intent", INTENT_HORIZON, road_events),
    ):
        k = round(horizon / dt)
        label = _labels(steps, pids, events, k)
        out[f"label_{key}"] = label
        out[f"keep_{key}"] = label | (steps + k <= last)
    return out


def collect(
    worlds: dict[str, ScenarioConfig], seeds: Sequence[int], max_steps: int | None = None
) -> dict[str, dict[str, np.ndarray]]:
    """`collect_episode` over worlds × seeds, concatenated per world with an ``episode`` index."""
    data: dict[str, dict[str, np.ndarray]] = {}
    for name, scenario in worlds.items():
        runs = [collect_episode(scenario, int(s), max_steps) for s in seeds]
        merged = {key: np.concatenate([r[key] for r in runs]) for key in runs[0]}
        merged["episode"] = np.concatenate([np.full(r["step"].size, e) for e, r in enumerate(runs)])
        data[name] = merged
    return data


def fit_logistic(x: np.ndarray, y: np.ndarray, l2: float = L2) -> dict[str, Any]:
    """L2-regularised logistic regression on standardised features (L-BFGS from zeros: deterministic)."""
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)
    z = (x - mean) / scale
    yf = y.astype(np.float64)
    n = max(len(yf), 1)

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        w, b = theta[:-1], theta[-1]
        logit = z @ w + b
        nll = np.logaddexp(0.0, logit) - yf * logit
        p = 0.5 * (1.0 + np.tanh(0.5 * logit))
        r = (p - yf) / n
        grad = np.concatenate([z.T @ r + l2 * w, [r.sum()]])
        return float(nll.sum() / n + 0.5 * l2 * w @ w), grad

    res = minimize(loss, np.zeros(z.shape[1] + 1), jac=True, method="L-BFGS-B", options={"maxiter": 2000})
    return {
        "mean": mean.tolist(),
        "scale": scale.tolist(),
        "coef": res.x[:-1].tolist(),
        "bias": float(res.x[-1]),
        "samples": len(yf),
        "positives": int(yf.sum()),
    }


def fit_platt(raw: np.ndarray, y: np.ndarray) -> list[float]:
    """Platt coefficients (a, b) of ``sigmoid(a logit(raw) + b)`` (unpenalised logistic regression)."""
    p = np.clip(raw.astype(np.float64), 1e-6, 1.0 - 1e-6)
    head = fit_logistic(np.log(p / (1.0 - p))[:, None], y, l2=0.0)
    a = head["coef"][0] / head["scale"][0]
    return [float(a), float(head["bias"] - a * head["mean"][0])]


def rule_flags(features: np.ndarray) -> np.ndarray:
    """The rule baseline: off the road within 1.2 m of the kerb and not walking away (facing the road)."""
    f = {name: features[:, i] for i, name in enumerate(FEATURES)}
    return (f["kerb_offset"] > 0.0) & (f["kerb_offset"] <= 1.2) & (f["towards_road"] >= -0.25)


def rule_predict(features: np.ndarray, on_road: np.ndarray, rates: Sequence[float]) -> np.ndarray:
    """The rule baseline's probabilities: its training rate off the road, at the kerb, or on the road."""
    group = np.where(on_road, 2, rule_flags(features).astype(int))
    return np.asarray(rates, dtype=np.float64)[group]


def _release_stats(p: np.ndarray, y: np.ndarray, who: np.ndarray, threshold: float) -> tuple[float, float]:
    """(share of crossing pedestrians released at least once, share of non-crossing samples released)."""
    pos = y.astype(bool)
    _, inverse = np.unique(who[pos], return_inverse=True)
    minimum = np.full(inverse.max(initial=-1) + 1, np.inf)
    np.minimum.at(minimum, inverse, p[pos])
    missed = float(np.mean(minimum <= threshold)) if minimum.size else 0.0
    freed = float(np.mean(p[~pos] <= threshold)) if (~pos).any() else 0.0
    return missed, freed


def fit_all(data: dict[str, dict[str, np.ndarray]], meta: dict[str, Any]) -> dict[str, Any]:
    """Every fitted quantity of the weights file from collected training data."""
    pool = {key: np.concatenate([d[key] for d in data.values()]) for key in next(iter(data.values()))}
    world_ix = np.concatenate([np.full(d["step"].size, i) for i, d in enumerate(data.values())])
    heads, rules = {}, {}
    for key in HEADS:
        keep = pool[f"keep_{key}"]
        x, y, on_road = pool["features"][keep], pool[f"label_{key}"][keep], pool["on_road"][keep]
        heads[key] = fit_logistic(x, y)
        group = np.where(on_road, 2, rule_flags(x).astype(int))
        rules[key] = [float((y[group == g].sum() + 1) / ((group == g).sum() + 2)) for g in range(3)]
    keep = pool["keep_intent"]
    y = pool["label_intent"][keep]
    calibration = {v: fit_platt(pool[f"{v}_intent_raw"][keep], y) for v in ("qlb", "cbm")}
    cand = keep & pool["candidate"]
    who = (world_ix * 1_000_000 + pool["episode"] * 10_000 + pool["pid"])[cand]
    y_c = pool["label_intent"][cand]
    models = {
        "learned": predict(pool["features"][cand], heads["intent"]),
        "qlb": platt(pool["qlb_intent_raw"][cand], calibration["qlb"]),
        "classical": platt(pool["cbm_intent_raw"][cand], calibration["cbm"]),
    }
    release = {}
    for name, p in models.items():
        threshold = 0.0
        for t in RELEASE_GRID:
            if _release_stats(p, y_c, who, t)[0] <= RELEASE_MISS:
                threshold = t
        missed, freed = _release_stats(p, y_c, who, threshold)
        release[name] = {
            "threshold": threshold,
            "crossers_released": missed,
            "non_crosser_samples_released": freed,
        }
    return {
        "format": FORMAT,
        "features": list(FEATURES),
        "intent_horizon": INTENT_HORIZON,
        "heads": heads,
        "calibration": calibration,
        "rule_rates": rules,
        "release": {
            "max_crossers_released": RELEASE_MISS,
            "candidates": int(cand.sum()),
            "crossing_pedestrians": int(np.unique(who[y_c.astype(bool)]).size),
            "models": release,
        },
        "training": meta,
    }


def train(
    episodes: int = 8, seed: int = 0, max_steps: int | None = None, worlds: Sequence[str] | None = None
) -> dict[str, Any]:
    """Collect the training data and fit everything (see the module docstring)."""
    seeds = list(range(seed, seed + episodes))
    clash = sorted(set(seeds) & set(EVAL_SEEDS))
    if clash:
        raise ValueError(f"training seeds {clash[:5]}… overlap the evaluation seeds {EVAL_SEEDS}")
    all_worlds = train_worlds()
    chosen = {n: all_worlds[n] for n in (worlds or all_worlds)}
    data = collect(chosen, seeds, max_steps)
    meta = {
        "worlds": list(chosen),
        "seeds": [seeds[0], seeds[-1]],
        "max_steps": max_steps,
        "l2": L2,
        "command": f"python -m studies.train_learned_intent --episodes {episodes} --seed {seed}",
    }
    return fit_all(data, meta)


def write_weights(weights: dict[str, Any], path: Path = WEIGHTS_PATH) -> str:
    """Write the weights JSON and its manifest; returns the sha256."""
    text = json.dumps(weights, indent=1, sort_keys=True) + "\n"
    digest = sha256_bytes(text.encode("utf-8"))
    write_text_atomic(path, text)
    manifest = path.with_name(MANIFEST_PATH.name)
    write_text_atomic(manifest, json.dumps({path.name: digest}, indent=1) + "\n")
    return digest
