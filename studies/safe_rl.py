"""Safe RL over seeds: PPO-Lagrangian and shielded PPO, trained on every built-in scenario, 3 seeds each.

    python -m studies.safe_rl --runs runs/safe_rl            # train what is missing, then analyse
    python -m studies.safe_rl --runs runs/safe_rl --no-train # analyse finished runs only

Training runs ``examples/ppo_crossing.py`` once per (learner, seed) with the recipe in `RECIPE` (a
behaviour-cloning warm start from `yielding`, then PPO), skipping runs whose ``model.policy.npz`` exists.
The analysis writes, from the runs' ``episodes.csv`` and checkpoints:

- **curves** (``curves.csv`` and ``curves.png`` in ``--figures``): return, episode cost, collision rate,
  yield compliance and censored delay of the training episodes against env steps and wall-clock seconds, in
  bins; per bin the mean over seeds and a 95 % t-interval (`scipy.stats.t`) across the seeds' bin means;
- **steps to safety** per scenario: for each checkpoint (``step_N.policy.npz``) the greedy policy on
  `SELECTION_SEED` episodes (45 per scenario, ``--safety-episodes``; seeds `crossing-eval` does not use)
  beside `yielding` on the same episodes; the first N at which it has no more collisions than `yielding`
  and at least its yield compliance there;
- **selection and evaluation**: each learner's seed with the best final policy on the selection episodes
  (fewest collisions, then best compliance, then lowest censored delay) is evaluated on `crossing-eval`'s
  default seeds, paired with `yielding` (same scenario and episode seed), with a bootstrap interval of the
  paired delay difference; beside them ``shield_max``, the shielded learner's starting point (`yielding`
  plus the full residual through the shield, not learned), so the table shows what learning adds to it.

Everything measured goes to ``benchmarks/results/safe_rl.json``; the results registry renders its tables
into ``docs/rl.md`` (``python -m benchmarks.results --render``).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
ALGOS = ("ppo_lagrangian", "shielded")
SEEDS = (0, 1, 2)
RECIPE = (
    "--timesteps", "50000", "--n-envs", "8", "--n-steps", "256", "--eval-every", "10000",
    "--eval-episodes", "0",
)  # fmt: skip
"""Training settings shared by every run (plus ``--algo``, ``--seed``, ``--out`` and `LEARNER_RECIPE`)."""
LEARNER_RECIPE = {
    "ppo_lagrangian": ("--learning-rate", "1e-4", "--bc-steps", "20000", "--log-std-init", "-1.5"),
    "shielded": (
        "--learning-rate",
        "3e-4",
        "--residual",
        "2",
        "--residual-offset",
        "1",
        "--log-std-init",
        "-1",
        "--time-reward",
        "-1",
    ),
}
"""Per learner: PPO-Lagrangian starts from a 20,000-step imitation of `yielding` (behaviour cloning); the
shielded learner is a residual on the rule (±2 m/s² per unit) offset by +1, so an untrained actor asks for
the most the shield allows (envelope-max, `SHIELD_MAX`) and learns where holding back pays; it needs none.
The shield carries its safety, so its training reward weighs time five times the env's default (−1 per
second instead of −0.2: a second saved is worth as much as a second of near miss avoided) and it learns at
SB3's default rate; both make the weak signal of a second gained count within 50,000 steps (docs/rl.md)."""
SELECTION_SEED = 777
"""Base seed of the selection and steps-to-safety episodes (`crossing-eval` defaults to 2024)."""
EVALUATION_SEED = 2024
"""`crossing-eval`'s default base seed: the evaluation episodes."""
SHIELD_MAX = "agents.registry:shield_max_policy"
"""The envelope-max reference (`agents.registry.shield_max_policy`: `yielding` + the full residual through
the shield, not learned): the shielded learner's starting point, evaluated beside it as ``shield_max``."""
METRICS = ("return", "cost", "collision", "compliance", "censored_delay")
RANGES = {
    "collision": (0.0, 1.0),
    "compliance": (0.0, 1.0),
    "cost": (0.0, np.inf),
    "multiplier": (0.0, np.inf),
}
"""Where a metric's values can lie: the figures clip their bands to it (three seeds give t-intervals that
reach past a rate's 0 and 1); the CSVs keep the intervals as computed."""


def train(runs: Path, algos: tuple[str, ...], seeds: tuple[int, ...]) -> dict[str, float]:
    """Run the missing trainings one after another; returns each run's wall-clock seconds (new runs only)."""
    times: dict[str, float] = {}
    for algo in algos:
        for seed in seeds:
            out = runs / algo / f"seed_{seed}"
            if (out / "model.policy.npz").is_file():
                continue
            t0 = time.perf_counter()
            cmd = [sys.executable, str(REPO / "examples" / "ppo_crossing.py"), "--algo", algo, *RECIPE]
            cmd += LEARNER_RECIPE[algo]
            cmd += ["--seed", str(seed), "--out", str(out), "--no-progress"]
            print(" ".join(cmd[1:]), file=sys.stderr)
            subprocess.run(cmd, check=True)
            times[f"{algo}/seed_{seed}"] = time.perf_counter() - t0
    return times


def _read_episodes(path: Path) -> dict[str, np.ndarray]:
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    cols = {k: np.array([r[k] for r in rows]) for k in (rows[0] if rows else {})}
    out = {k: v.astype(float) for k, v in cols.items() if k != "scenario"}
    out["scenario"] = cols.get("scenario", np.array([]))
    return out


def _bin_means(ep: dict[str, np.ndarray], axis: str, edges: np.ndarray) -> dict[str, np.ndarray]:
    """Per bin of `axis` (``step`` or ``wall_s``): the training episodes' metrics (NaN for an empty bin)."""
    idx = np.digitize(ep[axis], edges[1:-1])
    delay = np.where(np.isnan(ep["delay"]), ep["duration"], ep["delay"])
    out = {m: np.full(len(edges) - 1, np.nan) for m in METRICS}
    for b in range(len(edges) - 1):
        sel = idx == b
        if not sel.any():
            continue
        out["return"][b] = ep["return"][sel].mean()
        out["cost"][b] = ep["cost"][sel].mean()
        out["collision"][b] = ep["collision"][sel].mean()
        obligations = ep["obligations"][sel].sum()
        out["compliance"][b] = 1.0 - ep["violations"][sel].sum() / obligations if obligations else np.nan
        out["censored_delay"][b] = delay[sel].mean()
    return out


def mean_interval(values: np.ndarray) -> tuple[float, float, float]:
    """Mean over seeds (rows with NaN left out) and its 95 % t-interval; NaN interval with fewer than 2."""
    from scipy import stats

    v = values[np.isfinite(values)]
    if v.size == 0:
        return float("nan"), float("nan"), float("nan")
    if v.size < 2:
        return float(v[0]), float("nan"), float("nan")
    low, high = (
        stats.t.interval(0.95, v.size - 1, loc=v.mean(), scale=stats.sem(v)) if v.std() > 0 else (v[0], v[0])
    )
    return float(v.mean()), float(low), float(high)


def curves(
    runs: Path, algos: tuple[str, ...], seeds: tuple[int, ...], bins: int = 10
) -> list[dict[str, Any]]:
    """Rows (algo, axis, metric, bin centre, mean, low, high, seeds) of the learning curves."""
    rows: list[dict[str, Any]] = []
    for algo in algos:
        eps = [_read_episodes(runs / algo / f"seed_{s}" / "episodes.csv") for s in seeds]
        eps = [e for e in eps if e["step"].size]
        for axis in ("step", "wall_s"):
            top = max(float(e[axis].max()) for e in eps)
            edges = np.linspace(0.0, top * (1 + 1e-9), bins + 1)
            per_seed = [_bin_means(e, axis, edges) for e in eps]
            centres = 0.5 * (edges[1:] + edges[:-1])
            for m in METRICS:
                stacked = np.array([p[m] for p in per_seed])
                for b, c in enumerate(centres):
                    mean, low, high = mean_interval(stacked[:, b])
                    rows.append(
                        {"algo": algo, "axis": axis, "metric": m, "x": round(float(c), 1), "mean": mean,
                         "low": low, "high": high, "seeds": int(np.isfinite(stacked[:, b]).sum())}
                    )  # fmt: skip
    return rows


def plot_curves(rows: list[dict[str, Any]], png: Path) -> None:
    """Two rows of panels (against steps, against wall-clock), one per metric; mean and clipped 95 % band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    titles = {"return": "return", "cost": "episode cost", "collision": "collision rate",
              "compliance": "yield compliance", "censored_delay": "censored delay (s)"}  # fmt: skip
    fig, axes = plt.subplots(2, len(METRICS), figsize=(4 * len(METRICS), 6.5))
    for row, axis in enumerate(("step", "wall_s")):
        for col, m in enumerate(METRICS):
            ax = axes[row, col]
            for algo, style in zip(ALGOS, ("-", "--"), strict=True):
                pts = [r for r in rows if r["algo"] == algo and r["axis"] == axis and r["metric"] == m]
                if not pts:
                    continue
                x = np.array([p["x"] for p in pts])
                y = np.array([p["mean"] for p in pts])
                lo, hi = np.clip(
                    [[p["low"] for p in pts], [p["high"] for p in pts]], *RANGES.get(m, (-np.inf, np.inf))
                )
                line = ax.plot(x, y, style, marker="o", ms=3, label=algo)[0]
                ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.2)
            ax.set_title(titles[m])
            ax.set_xlabel("env steps" if axis == "step" else "wall-clock s (2 cores, shared)")
            ax.grid(alpha=0.3)
    axes[0, 0].legend()
    fig.suptitle(
        "Training episodes (exploration on), 3 seeds: mean and 95 % t-interval across seeds"
        " (clipped to the metric's range)"
    )
    fig.tight_layout()
    fig.savefig(png, dpi=80)
    plt.close(fig)


def read_curve_rows(path: Path, text: tuple[str, ...]) -> list[dict[str, Any]]:
    """Rows of a curves CSV (this module's or `studies.safe_rl_long`'s), numbers as floats but `text`.

    What a figure is drawn again from, with no episodes run.
    """
    with path.open() as fh:
        return [{k: (v if k in text else float(v)) for k, v in r.items()} for r in csv.DictReader(fh)]


def replot(figures: Path) -> None:
    """Draw ``rl_curves.png`` again from the measured ``rl_curves.csv`` beside it (no episodes run)."""
    rows = read_curve_rows(figures / "rl_curves.csv", text=("algo", "axis", "metric", "seeds"))
    plot_curves(rows, figures / "rl_curves.png")


def _evaluate(
    specs: list[str], scenarios: list[str], episodes: int, base_seed: int, workers: int
) -> list[Any]:
    from crossing_eval.runners import run_tasks
    from crossing_eval.tasks import make_tasks

    return run_tasks(
        make_tasks(scenarios, specs, episodes, base_seed), workers, "local", None, show_progress=False
    )


@cache
def _duration(scenario: str) -> float:
    """A scenario's duration: the censoring horizon of `crossing_eval.statistics.censored_delay`."""
    from scenarios import load_scenario

    return load_scenario(scenario).duration


def _censored(records: list[Any]) -> np.ndarray:
    """Each record's censored delay: its delay if it passed, else its scenario's duration."""
    return np.array(
        [r.result["delay"] if r.result["passed_crossing"] else _duration(r.task.scenario) for r in records]
    )


def scores(records: list[Any]) -> dict[str, float]:
    """Collisions, compliance and censored delay of a list of records."""
    from crossing_eval.statistics import censored_delay

    res = [r.result for r in records]
    obligations = sum(r["yield_obligations"] for r in res)
    violations = sum(r["yield_violations"] for r in res)
    delay = censored_delay(
        [r["delay"] for r in res],
        [r["passed_crossing"] for r in res],
        [_duration(r.task.scenario) for r in records],
    )
    return {
        "episodes": len(res),
        "collisions": int(sum(bool(r["collision"]) for r in res)),
        "obligations": int(obligations),
        "compliance": 1.0 - violations / obligations if obligations else float("nan"),
        "censored_delay": float(delay["censored_mean_delay"]),
    }


def steps_to_safety(runs: Path, algo: str, seed: int, scenarios: list[str], episodes: int, workers: int,
                    reference: dict[str, dict[str, float]]) -> dict[str, int | None]:  # fmt: skip
    """Per scenario: the first checkpoint step whose greedy policy matches `yielding`'s safety (or None).

    Checkpoints are tried in order, each on the scenarios not yet reached only (on `episodes` selection
    episodes per scenario), so a learner that is safe from the start costs one checkpoint.
    """
    folder = runs / algo / f"seed_{seed}"
    steps = sorted(int(p.name.split("_")[1].split(".")[0]) for p in folder.glob("step_*.policy.npz"))
    first: dict[str, int | None] = {s: None for s in scenarios}
    for n in steps:
        todo = [s for s in scenarios if first[s] is None]
        if not todo:
            break
        spec = f"mlp:{(folder / f'step_{n}.policy.npz').resolve()}"
        records = _evaluate([spec], todo, episodes, SELECTION_SEED, workers)
        for s in todo:
            sc = scores([r for r in records if r.task.scenario == s])
            ref = reference[s]
            ok_compliance = np.isnan(ref["compliance"]) or sc["compliance"] >= ref["compliance"] - 1e-9
            if sc["collisions"] <= ref["collisions"] and ok_compliance:
                first[s] = n
    return first


def paired_delay_difference(a: list[Any], b: list[Any], rng_seed: int = 0) -> dict[str, float]:
    """Mean censored delay of `a` minus `b` on paired episodes, relative to `b`, with a 95 % bootstrap CI."""
    from scipy import stats

    def delays(records: list[Any]) -> dict[tuple[str, int], float]:
        return dict(
            zip(((r.task.scenario, r.task.episode) for r in records), _censored(records), strict=True)
        )

    da, db = delays(a), delays(b)
    keys = sorted(set(da) & set(db))
    diff = np.array([da[k] - db[k] for k in keys])
    base = np.array([db[k] for k in keys])
    boot = stats.bootstrap(
        (diff, base), lambda d, x: d.mean() / x.mean(), paired=True, vectorized=False, n_resamples=2000,
        random_state=np.random.default_rng(rng_seed), method="percentile",
    )  # fmt: skip
    return {
        "pairs": len(keys),
        "relative_change": float(diff.mean() / base.mean()),
        "low": float(boot.confidence_interval.low),
        "high": float(boot.confidence_interval.high),
    }


def analyse(
    runs: Path, figures: Path, episodes: int, check_episodes: int, workers: int, safety_episodes: int
) -> dict[str, Any]:
    """Curves, steps to safety, selection and the paired evaluation (see the module docstring)."""
    from scenarios import list_scenarios

    scenarios = sorted(list_scenarios())
    rows = curves(runs, ALGOS, SEEDS)
    figures.mkdir(parents=True, exist_ok=True)
    with (figures / "rl_curves.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot_curves(rows, figures / "rl_curves.png")

    # Yielding on the selection episodes: the safety reference of steps-to-safety.
    yield_sel = _evaluate(["yielding"], scenarios, safety_episodes, SELECTION_SEED, workers)
    reference = {s: scores([r for r in yield_sel if r.task.scenario == s]) for s in scenarios}
    result: dict[str, Any] = {
        "recipe": list(RECIPE),
        "learner_recipe": {k: list(v) for k, v in LEARNER_RECIPE.items()},
        "seeds": list(SEEDS),
        "check_episodes": check_episodes,
        "safety_episodes": safety_episodes,
        "evaluation_episodes": episodes,
        "learners": {},
    }
    chosen = {}
    for algo in ALGOS:
        per_seed = {}
        for seed in SEEDS:
            first = steps_to_safety(runs, algo, seed, scenarios, safety_episodes, workers, reference)
            final = f"mlp:{(runs / algo / f'seed_{seed}' / 'model.policy.npz').resolve()}"
            sel = scores(_evaluate([final], scenarios, check_episodes, SELECTION_SEED, workers))
            train_s = float(_read_episodes(runs / algo / f"seed_{seed}" / "episodes.csv")["wall_s"].max())
            per_seed[seed] = {"steps_to_safety": first, "selection": sel, "train_wall_s": train_s}
        best = min(
            SEEDS,
            key=lambda s: (per_seed[s]["selection"]["collisions"], -per_seed[s]["selection"]["compliance"],
                           per_seed[s]["selection"]["censored_delay"]),
        )  # fmt: skip
        chosen[algo] = best
        result["learners"][algo] = {"per_seed": per_seed, "chosen_seed": best}

    learned = [f"mlp:{(runs / a / f'seed_{chosen[a]}' / 'model.policy.npz').resolve()}" for a in ALGOS]
    specs = ["yielding", *learned, SHIELD_MAX]
    records = _evaluate(specs, scenarios, episodes, EVALUATION_SEED, workers)
    by_spec = {s: [r for r in records if r.task.policy == s] for s in specs}
    evaluation = {"yielding": scores(by_spec["yielding"])}
    for algo, spec in zip((*ALGOS, "shield_max"), specs[1:], strict=True):
        evaluation[algo] = scores(by_spec[spec])
        evaluation[algo]["delay_vs_yielding"] = paired_delay_difference(by_spec[spec], by_spec["yielding"])
    result["evaluation"] = evaluation
    return result


def _fmt(x: float, digits: int = 3) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def _evaluation_rows(data: dict[str, Any]) -> list[str]:
    ev = data["evaluation"]
    rows = [
        "| policy | episodes | collisions | yield compliance (obligations) | censored delay s |"
        " delay vs yielding [95 % CI] |",
        "|---|---|---|---|---|---|",
    ]
    shipped = {  # `agents.SHIPPED_POLICIES`, and the reference that is not learned
        "ppo_lagrangian": "ppo_lagrangian",
        "shielded": "ppo_shielded",
        "shield_max": "shield_max (not learned: the shielded learner's start, yielding + full residual)",
    }
    for name in ("yielding", *ALGOS, "shield_max"):
        if name not in ev:  # results measured before the reference row was added
            continue
        e = ev[name]
        change = e.get("delay_vs_yielding")
        cell = (
            f"{100 * change['relative_change']:+.1f} %"
            f" [{100 * change['low']:+.1f}, {100 * change['high']:+.1f}]"
            if change
            else "-"
        )
        rows.append(
            f"| {shipped.get(name, name)} | {e['episodes']} | {e['collisions']} |"
            f" {_fmt(e['compliance'])} ({e['obligations']}) |"
            f" {_fmt(e['censored_delay'], 2)} | {cell} |"
        )
    return rows


def render_summary(data: dict[str, Any]) -> str:
    """The README's block: the evaluation table of both learners beside `yielding`."""
    return "\n".join(
        [
            f"Safe RL, every built-in scenario, {data['evaluation_episodes']} paired episodes per scenario"
            " and policy (rendered from `benchmarks/results/safe_rl.json`; curves and method in"
            " [docs/rl.md](docs/rl.md)):",
            "",
            *_evaluation_rows(data),
        ]
    )


def render_body(data: dict[str, Any]) -> str:
    """The markdown tables of a results JSON (the registry renders them into ``docs/rl.md``)."""
    lines = [
        f"Evaluation: `crossing-eval`'s default seeds, {data['evaluation_episodes']} episodes per scenario"
        " and policy on every built-in scenario, paired (same scenario and seed for each policy); the"
        " learners are each one's selected seed (below). Delay change: mean paired difference in censored"
        " delay relative to `yielding`'s mean, with a 95 % paired bootstrap interval.",
        "",
        *_evaluation_rows(data),
        "",
        "![Safe-RL learning curves over three seeds](rl_curves.png)",
    ]
    lines += [
        "",
        f"Selection (seed {SELECTION_SEED}, {data['check_episodes']} episodes per scenario, seeds"
        " `crossing-eval` does not use) of each seed's final policy, and the wall-clock of its PPO phase (the"
        " warm start not included; shared 2-core machine):",
        "",
        "| learner | seed | collisions | yield compliance | censored delay s | PPO wall-clock s | chosen |",
        "|---|---|---|---|---|---|---|",
    ]
    for algo in ALGOS:
        learner = data["learners"][algo]
        for seed, d in sorted(learner["per_seed"].items()):
            sel = d["selection"]
            lines.append(
                f"| {algo} | {seed} | {sel['collisions']} | {_fmt(sel['compliance'])} |"
                f" {_fmt(sel['censored_delay'], 2)} | {d['train_wall_s']:.0f} |"
                f" {'yes' if int(seed) == int(learner['chosen_seed']) else ''} |"
            )
    scenarios = sorted(next(iter(data["learners"][ALGOS[0]]["per_seed"].values()))["steps_to_safety"])
    lines += [
        "",
        "Steps to safety: the first checkpoint (env steps of PPO after the warm start; 0 = the warm start"
        " itself) whose greedy policy has no more collisions than `yielding` and at least its yield"
        f" compliance on the same {data['safety_episodes']} selection episodes"
        f" of the scenario (seed {SELECTION_SEED}, the first of them the selection's); one entry per seed,"
        " '-' = not reached by the last checkpoint.",
        "",
        "| scenario | " + " | ".join(ALGOS) + " |",
        "|---|" + "---|" * len(ALGOS),
    ]
    for sc in scenarios:
        cells = []
        for algo in ALGOS:
            per_seed = data["learners"][algo]["per_seed"]
            cells.append(
                ", ".join(
                    "-"
                    if per_seed[k]["steps_to_safety"][sc] is None
                    else f"{per_seed[k]['steps_to_safety'][sc]:,}"
                    for k in sorted(per_seed)
                )
            )
        lines.append(f"| {sc} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ship(runs: Path, chosen: dict[str, int]) -> dict[str, str]:
    """Copy each learner's chosen ``model.policy.npz`` into ``agents/weights`` and rewrite the manifest.

    ``ppo_lagrangian.npz`` and ``ppo_shielded.npz`` are the shipped policies of `agents.registry`; the
    manifest holds the sha256 of every file there. Returns the new manifest.
    """
    import hashlib
    import shutil

    from agents.registry import SHIPPED_MANIFEST, SHIPPED_POLICIES

    names = {"ppo_lagrangian": "ppo_lagrangian", "shielded": "ppo_shielded"}
    for algo, seed in chosen.items():
        target = SHIPPED_POLICIES[names[algo]]
        shutil.copyfile(runs / algo / f"seed_{seed}" / "model.policy.npz", target)
    manifest = {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(SHIPPED_POLICIES.values())
        if p.is_file()
    }
    SHIPPED_MANIFEST.write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return manifest


def main(argv: list[str] | None = None) -> int:
    """Train (unless --no-train), analyse, write the results JSON."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=Path, default=Path("runs/safe_rl"), help="folder of the training runs")
    p.add_argument("--figures", type=Path, default=REPO / "docs", help="where rl_curves.csv/png go")
    p.add_argument("--no-train", action="store_true", help="analyse finished runs only")
    p.add_argument("--episodes", type=int, default=35, help="evaluation episodes per scenario and policy")
    p.add_argument("--check-episodes", type=int, default=4, help="selection episodes per scenario")
    p.add_argument(
        "--safety-episodes", type=int, default=45, help="steps-to-safety episodes per scenario and checkpoint"
    )
    p.add_argument("--workers", type=int, default=2, help="evaluation worker processes")
    p.add_argument("--ship", action="store_true", help="copy the chosen policies into agents/weights")
    p.add_argument(
        "--replot", action="store_true", help="only draw rl_curves.png again from rl_curves.csv in --figures"
    )
    p.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "safe_rl_measured.json")
    a = p.parse_args(argv)
    if a.replot:
        replot(a.figures)
        return 0
    times = {} if a.no_train else train(a.runs, ALGOS, SEEDS)
    t0 = time.perf_counter()
    result = analyse(a.runs, a.figures, a.episodes, a.check_episodes, a.workers, a.safety_episodes)
    result["new_training_wall_s"] = times
    result["analysis_wall_s"] = round(time.perf_counter() - t0, 1)
    if a.ship:
        result["shipped"] = ship(a.runs, {k: v["chosen_seed"] for k, v in result["learners"].items()})
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    print(json.dumps(result["evaluation"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
