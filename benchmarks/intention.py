"""Benchmark the crossing-intention predictors against ground truth: Brier, AUC and calibration (ECE).

Runs `EPISODES` episodes (seeds 1000 onwards, disjoint from the training seeds of the learned model) in
three worlds: the default road with spawn_rate 20/min and classical ("gap") pedestrians, the same with QLB
("qlb") pedestrians, and the built-in ``busy_zebra``; the ego is `cautious_action` (observation only; it
stops for anyone waiting at the kerb). Every (step, present pedestrian slot) is a sample
(`predictors.learned_intent_train.collect_episode`). Targets: for h = 1, 2, 4 s, whether ground truth has
the pedestrian on the carriageway ahead of the ego's rear at some step in [t, t + h] (what
``crossing_intention`` estimates); and "intent", whether it is on the carriageway anywhere within 10 s
(what ``crossing_intent`` estimates, the release signal). Samples whose window runs past the episode's end
are dropped unless already positive.

Models: the base rate (the evaluated samples' own pooled positive rate: an in-sample constant), the rule
baseline (at the kerb and not walking away: its training-seed rate), the learned logistic model, the
classical and QLB models (near-term as published; intent Platt-calibrated), and the oracle (the true
intent, 0.5 while undecided; the same value for every target). Intervals: 95 % percentile bootstrap over
whole episodes (`DRAWS` draws; samples within an episode are correlated), also for the paired difference
of each model's Brier score from the base rate's.

    python -m benchmarks.intention                    # print the tables (about 3 minutes on 2 cores)
    python -m benchmarks.results intention            # measure into the registry and render
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import numpy as np

from predictors.learned_intent import predict
from predictors.learned_intent_train import (
    EVAL_SEEDS,
    benchmark_worlds,
    cautious_action,
    collect,
    rule_predict,
)
from predictors.learned_intent_weights import WEIGHTS_PATH, platt, sha256_bytes, shipped_weights

__all__ = ["brier", "cautious_action", "ece", "evaluate", "render_body", "roc_auc"]

TARGETS = ("1", "2", "4", "intent")
"""Near-term horizons (s) and the intent target."""
MODELS = ("base rate", "rule", "learned", "classical", "QLB", "oracle")
"""Rows of each table, in order."""
SUBSETS = ("all", "not on road")
"""All samples, and those whose pedestrian is not yet on the road (the ones that need a prediction)."""
EPISODES = 12
"""Default episodes (seeds) per world."""
SEED = 1000
"""Default first evaluation seed."""
DRAWS = 300
"""Bootstrap draws."""
BINS = 10
"""Equal-width probability bins of the ECE."""


def roc_auc(scores: np.ndarray, labels: np.ndarray, weights: np.ndarray | None = None) -> float:
    """ROC AUC (the Mann-Whitney statistic, ties counted one half), optionally with sample weights."""
    _, inverse = np.unique(np.asarray(scores, dtype=np.float64), return_inverse=True)
    return _auc(inverse, labels.astype(bool), weights)


def _auc(inverse: np.ndarray, pos: np.ndarray, weights: np.ndarray | None) -> float:
    w = np.ones(pos.size) if weights is None else weights
    n = int(inverse.max(initial=-1)) + 1
    p = np.bincount(inverse, weights=w * pos, minlength=n)
    q = np.bincount(inverse, weights=w * ~pos, minlength=n)
    total_p, total_q = p.sum(), q.sum()
    if total_p <= 0.0 or total_q <= 0.0:
        return float("nan")
    below = np.cumsum(q) - q
    return float((p * (below + 0.5 * q)).sum() / (total_p * total_q))


def brier(scores: np.ndarray, labels: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Mean squared error of probabilities against 0/1 labels (optionally weighted)."""
    return float(np.average((scores - labels) ** 2, weights=weights))


def ece(scores: np.ndarray, labels: np.ndarray, weights: np.ndarray | None = None, bins: int = BINS) -> float:
    """Expected calibration error: sum over equal-width bins of (bin share) × |mean score − mean label|."""
    w = np.ones(scores.size) if weights is None else weights
    b = np.minimum((np.asarray(scores) * bins).astype(int), bins - 1)
    gap = np.bincount(b, weights=w * (scores - labels), minlength=bins)
    return float(np.abs(gap).sum() / w.sum())


def _predictions(d: dict[str, np.ndarray], target: str, weights: dict[str, Any]) -> dict[str, np.ndarray]:
    """Every model's probabilities for one target on the samples of `d`."""
    feats = d["features"]
    if target == "intent":
        cbm = platt(d["cbm_intent_raw"], weights["calibration"]["cbm"])
        qlb = platt(d["qlb_intent_raw"], weights["calibration"]["qlb"])
    else:
        cbm, qlb = d[f"cbm_{target}"], d[f"qlb_{target}"]
    return {
        "rule": rule_predict(feats, d["on_road"], weights["rule_rates"][target]),
        "learned": predict(feats, weights["heads"][target]),
        "classical": np.asarray(cbm, dtype=np.float64),
        "QLB": np.asarray(qlb, dtype=np.float64),
        "oracle": d["oracle"].astype(np.float64),
    }


def _row(
    preds: dict[str, np.ndarray], y: np.ndarray, episode: np.ndarray, episodes: int, seed: int
) -> dict[str, Any]:
    """Point values and bootstrap intervals of every model on one (world, subset, target).

    A bootstrap draw weights each episode by how often it was drawn, so every statistic is computed from
    per-episode sums (of squared errors, of calibration gaps per bin, of positives and negatives per score).
    """
    rate = float(y.mean()) if y.size else float("nan")
    preds = {"base rate": np.full(y.size, rate), **preds}
    pos = y.astype(bool)
    rng = np.random.default_rng(seed)
    counts = np.stack(
        [np.bincount(rng.integers(0, episodes, episodes), minlength=episodes) for _ in range(DRAWS)]
    )
    counts = counts.astype(np.float64)  # (D, E)
    n_e = np.bincount(episode, minlength=episodes).astype(np.float64)
    base_sq = (preds["base rate"] - y) ** 2
    out: dict[str, Any] = {"samples": int(y.size), "positives": int(pos.sum()), "models": {}}
    for m, p in preds.items():
        sq = (p - y) ** 2
        bins = np.minimum((p * BINS).astype(int), BINS - 1)
        _, inv = np.unique(p, return_inverse=True)
        u = int(inv.max(initial=-1)) + 1
        sq_e = np.bincount(episode, weights=sq, minlength=episodes)
        diff_e = np.bincount(episode, weights=sq - base_sq, minlength=episodes)
        gap_e = np.bincount(episode * BINS + bins, weights=p - y, minlength=episodes * BINS)
        gap_e = gap_e.reshape(episodes, BINS)
        pos_e = np.bincount(episode * u + inv, weights=pos, minlength=episodes * u).reshape(episodes, u)
        neg_e = np.bincount(episode * u + inv, weights=~pos, minlength=episodes * u).reshape(episodes, u)
        total = counts @ n_e
        stats = [
            counts @ sq_e / total,
            counts @ diff_e / total,
            np.empty(DRAWS),
            np.abs(counts @ gap_e).sum(1) / total,
        ]
        for start in range(0, DRAWS, 50):
            c = counts[start : start + 50]
            pp, qq = c @ pos_e, c @ neg_e
            below = np.cumsum(qq, axis=1) - qq
            with np.errstate(invalid="ignore", divide="ignore"):
                stats[2][start : start + 50] = (pp * (below + 0.5 * qq)).sum(1) / (pp.sum(1) * qq.sum(1))
        point = (brier(p, y), brier(p, y) - brier(preds["base rate"], y), _auc(inv, pos, None), ece(p, y))
        out["models"][m] = {
            name: [float(point[i]), float(np.nanpercentile(st, 2.5)), float(np.nanpercentile(st, 97.5))]
            for i, (name, st) in enumerate(
                zip(("brier", "brier_minus_base", "auc", "ece"), stats, strict=True)
            )
        }
    return out


def evaluate(episodes: int = EPISODES, seed: int = SEED) -> dict[str, Any]:
    """Run the seed set in every world and score every model (the registry's JSON data)."""
    seeds = list(range(seed, seed + episodes))
    if not set(seeds) <= set(EVAL_SEEDS):
        raise ValueError(f"evaluation seeds must lie in {EVAL_SEEDS} (the training seeds lie outside it)")
    weights = shipped_weights()
    start = time.perf_counter()
    data = collect(benchmark_worlds(), seeds)
    results: dict[str, Any] = {}
    for world, d in data.items():
        for subset in SUBSETS:
            for target in TARGETS:
                keep = d[f"keep_{target}"] & (~d["on_road"] if subset == "not on road" else True)
                sub = {k: v[keep] for k, v in d.items()}
                preds = _predictions(sub, target, weights)
                y = sub[f"label_{target}"].astype(np.float64)
                results[f"{world}|{subset}|{target}"] = _row(preds, y, sub["episode"], episodes, seed)
    return {
        "command": f"python -m benchmarks.intention --episodes {episodes} --seed {seed}",
        "episodes": episodes,
        "seeds": [seeds[0], seeds[-1]],
        "worlds": list(data),
        "draws": DRAWS,
        "weights_sha256": sha256_bytes(WEIGHTS_PATH.read_bytes()),
        "training": weights["training"],
        "release": weights["release"],
        "seconds": round(time.perf_counter() - start, 1),
        "results": results,
    }


def _ci(v: list[float], digits: int = 3) -> str:
    return f"{v[0]:.{digits}f} [{v[1]:.{digits}f}, {v[2]:.{digits}f}]"


def _signed(v: list[float]) -> str:
    return f"{v[0]:+.4f} [{v[1]:+.4f}, {v[2]:+.4f}]"


def render_body(data: dict[str, Any]) -> str:
    """The markdown tables from the JSON data."""
    res = data["results"]
    lines = [
        f"Measured with `{data['command']}` ({data['episodes']} episodes per world, seeds"
        f" {data['seeds'][0]}..{data['seeds'][1]}, {data['seconds']:.0f} s on 2 cores) on commit"
        f" `{str(data.get('commit', 'unknown'))[:12]}`; learned weights sha256"
        f" `{data['weights_sha256'][:12]}` (trained with `{data['training']['command']}`, seeds"
        f" {data['training']['seeds'][0]}..{data['training']['seeds'][1]});"
        " rendered from `benchmarks/results/intention.json` by `python -m benchmarks.results`."
        f" Intervals: 95 % bootstrap over episodes ({data['draws']} draws).",
    ]
    names = {"1": "h = 1 s", "2": "h = 2 s", "4": "h = 4 s", "intent": "intent (on the road within 10 s)"}
    for target in TARGETS:
        lines += [
            "",
            f"**{names[target]}, not on road**",
            "",
            "| world | model | Brier | Brier − base rate | AUC | ECE |",
            "|---|---|---|---|---|---|",
        ]
        for world in data["worlds"]:
            row = res[f"{world}|not on road|{target}"]
            for i, model in enumerate(MODELS):
                m = row["models"][model]
                label = f"{world} ({row['samples']} / {row['positives']})" if i == 0 else ""
                lines.append(
                    f"| {label} | {model} | {_ci(m['brier'], 4)} | {_signed(m['brier_minus_base'])}"
                    f" | {_ci(m['auc'])} | {_ci(m['ece'])} |"
                )
    lines += [
        "",
        "**All samples (on the road included): Brier score**",
        "",
        "| world | target | samples / positives | " + " | ".join(MODELS) + " |",
        "|---|---|---|" + "---|" * len(MODELS),
    ]
    for world in data["worlds"]:
        for target in TARGETS:
            row = res[f"{world}|all|{target}"]
            cells = " | ".join(f"{row['models'][m]['brier'][0]:.4f}" for m in MODELS)
            lines.append(f"| {world} | {names[target]} | {row['samples']} / {row['positives']} | {cells} |")
    rel = data["release"]
    closed = rel.get("closed_loop")
    if closed is None:
        how = "chosen on the training seeds (open loop, below)"
    else:
        how = (
            f"chosen in closed loop by `{closed['command']}`: `{closed['policy']}` on every built-in"
            f" scenario, {closed['episodes_per_scenario']} selection episodes each (base seed"
            f" {closed['seed']}, never evaluated), the bound raised in steps of 0.05 until a step has a"
            f" collision or yield compliance below {closed['min_compliance']:.2f}; the kept bound is the last"
            " step before it"
        )
        if "confirmations" in closed:
            how += (
                f", then confirmed on {closed['confirm_episodes_per_scenario']} further episodes per scenario"
                f" (base seed {closed['confirm_seed']}) and stepped down until it passes there too"
            )
    lines += [
        "",
        f"**Release risk bounds**: {how}. The open-loop bound is the training's proxy: the largest"
        f" threshold at which at most {rel['max_crossers_released']:.0%} of the {rel['crossing_pedestrians']}"
        " pedestrians who cross within 10 s are *ever* released while standing by the kerb at a zebra ahead"
        f" ({rel['candidates']} candidate samples; the release shares are at that bound).",
        "",
        "| model | release bound | open-loop bound | crossers released | non-crosser samples released |",
        "|---|---|---|---|---|",
    ]
    for model, r in rel["models"].items():
        lines.append(
            f"| {model} | {r['threshold']:.3f} | {r.get('open_loop_threshold', r['threshold']):.3f}"
            f" | {r['crossers_released']:.3f} | {r['non_crosser_samples_released']:.3f} |"
        )
    if closed is not None:
        title = "Closed-loop sweep (every step run; the last one of each model failed, or ended the grid):"
        lines += _sweep_table(title, closed["sweeps"])
        if "confirmations" in closed:
            title = (
                "Confirmation of the kept bounds (from the kept bound down; the last one run is the release"
                " bound unless every one failed):"
            )
            lines += _sweep_table(title, closed["confirmations"])
    return "\n".join(lines)


SWEEP_HEADER = "| model | bound | episodes | collisions | compliant / obligations | mean episode duration s |"


def _sweep_table(title: str, sweeps: dict[str, list[dict[str, Any]]]) -> list[str]:
    """Markdown lines of closed-loop release-bound points, one row per (model, bound) run."""
    lines = ["", title, "", SWEEP_HEADER, "|---|---|---|---|---|---|"]
    for model, points in sweeps.items():
        lines += [
            f"| {model} | {pt['bound']:.2f} | {pt['episodes']} | {pt['collisions']} |"
            f" {pt['compliant']} / {pt['obligations']} | {pt['mean_duration']:.2f} |"
            for pt in points
        ]
    return lines


def main(argv: list[str] | None = None) -> int:
    """Print the tables (the registry entry ``intention`` stores and renders them)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=EPISODES, help="episodes (seeds) per world")
    parser.add_argument("--seed", type=int, default=SEED, help="first seed of the fixed seed set")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        print(f"error: --episodes must be >= 1, got {args.episodes}", file=sys.stderr)
        return 2
    print(render_body(evaluate(args.episodes, args.seed)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
