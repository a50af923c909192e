"""Where PPO-Lagrangian stalls: the safe-RL study's Lagrangian recipe six times as long, at two budgets.

    python -m studies.safe_rl_long --runs runs/safe_rl_long            # train what is missing, then analyse
    python -m studies.safe_rl_long --runs runs/safe_rl_long --no-train # analyse finished runs only

The recipe is `studies.safe_rl`'s for ``ppo_lagrangian`` (the same warm start, learning rate and rollout
size) with `LONG_TIMESTEPS` PPO steps instead of 50,000, a checkpoint every `CHECKPOINT_EVERY` steps, and
each cost budget of `BUDGETS` (3 seeds each, in ``runs/budget_B/seed_S``). The analysis writes, from the
runs' ``episodes.csv`` and checkpoints:

- **training curves** (``rl_lagrangian_long.csv`` and ``.png`` in ``--figures``): episode cost, collision
  rate, yield compliance, censored delay and the multiplier λ of the training episodes (exploration on)
  against env steps, per budget and seed, and the mean over seeds with a 95 % t-interval across them;
- **greedy checkpoints**: every checkpoint's deterministic policy on `SELECTION_SEED` episodes
  (``--episodes`` per scenario, seeds `crossing-eval` does not use) beside `yielding` on the same episodes:
  collisions, yield compliance, censored delay, mean episode cost and the number of scenarios where it is
  as safe as `yielding` (no more collisions, at least its compliance) — the curve a deployed policy would
  follow.

Everything measured goes to ``benchmarks/results/safe_rl_long.json``; the results registry renders it into
``docs/rl.md`` (``python -m benchmarks.results --render``).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from studies import safe_rl

REPO = Path(__file__).resolve().parents[1]
ALGO = "ppo_lagrangian"
LONG_TIMESTEPS = 300_000
"""PPO steps after the warm start: six times `studies.safe_rl`'s recipe."""
CHECKPOINT_EVERY = 50_000
"""Steps between the checkpoints whose greedy policies are evaluated."""
BINS = 15
"""Training-curve bins over the env steps (20,000 steps each)."""
BUDGETS = (2.0, 1.0)
"""Cost budgets per episode: the recipe's (`crossing_env.constrained.CostBudget`'s default), within which a
policy that collides in one episode of twelve can stay (a collision costs several times the budget with the
near-miss steps before it), and one at about `yielding`'s own mean cost, which leaves collisions half the
room."""
CURVE_METRICS = ("cost", "collision", "compliance", "censored_delay", "multiplier")


def recipe(budget: float) -> list[str]:
    """`studies.safe_rl`'s Lagrangian command line with the long run's steps, checkpoints and `budget`."""
    args = [*safe_rl.RECIPE, *safe_rl.LEARNER_RECIPE[ALGO]]
    for flag, value in (("--timesteps", LONG_TIMESTEPS), ("--eval-every", CHECKPOINT_EVERY)):
        args[args.index(flag) + 1] = str(value)
    return [*args, "--cost-budget", f"{budget:g}"]


def run_folder(runs: Path, budget: float, seed: int) -> Path:
    """Where one run lives: ``runs/budget_B/seed_S``."""
    return runs / f"budget_{budget:.1f}" / f"seed_{seed}"


def train(runs: Path, seeds: tuple[int, ...]) -> dict[str, float]:
    """Run the missing trainings one after another; returns each new run's wall-clock seconds."""
    times: dict[str, float] = {}
    for budget in BUDGETS:
        for seed in seeds:
            out = run_folder(runs, budget, seed)
            if (out / "model.policy.npz").is_file():
                continue
            t0 = time.perf_counter()
            cmd = [
                sys.executable,
                str(REPO / "examples" / "ppo_crossing.py"),
                "--algo",
                ALGO,
                *recipe(budget),
            ]
            cmd += ["--seed", str(seed), "--out", str(out), "--no-progress"]
            print(" ".join(cmd[1:]), file=sys.stderr)
            subprocess.run(cmd, check=True)
            times[f"{out.parent.name}/{out.name}"] = time.perf_counter() - t0
    return times


def seed_curve(episodes: dict[str, np.ndarray], edges: np.ndarray) -> dict[str, np.ndarray]:
    """One seed's training episodes per step bin: `studies.safe_rl`'s metrics and the mean multiplier λ."""
    out = safe_rl._bin_means(episodes, "step", edges)
    idx = np.digitize(episodes["step"], edges[1:-1])
    out["multiplier"] = np.array(
        [
            episodes["multiplier"][idx == b].mean() if (idx == b).any() else np.nan
            for b in range(len(edges) - 1)
        ]
    )
    return out


def training_curves(runs: Path, seeds: tuple[int, ...]) -> list[dict[str, Any]]:
    """Rows (budget, metric, bin centre, per-seed values, mean, low, high) of the training curves."""
    rows = []
    for budget in BUDGETS:
        per_seed = {s: safe_rl._read_episodes(run_folder(runs, budget, s) / "episodes.csv") for s in seeds}
        top = max(float(e["step"].max()) for e in per_seed.values())
        edges = np.linspace(0.0, top * (1 + 1e-9), BINS + 1)
        centres = 0.5 * (edges[1:] + edges[:-1])
        bins = {s: seed_curve(e, edges) for s, e in per_seed.items()}
        for m in CURVE_METRICS:
            for b, c in enumerate(centres):
                values = np.array([bins[s][m][b] for s in seeds])
                mean, low, high = safe_rl.mean_interval(values)
                rows.append(
                    {"budget": budget, "metric": m, "x": round(float(c), 1), "mean": mean, "low": low,
                     "high": high, **{f"seed_{s}": float(v) for s, v in zip(seeds, values, strict=True)}}
                )  # fmt: skip
    return rows


def _at_yielding(records: list[Any], reference: dict[str, dict[str, float]]) -> int:
    """Scenarios where `records` have no more collisions than `yielding` and at least its compliance."""
    n = 0
    for scenario, ref in reference.items():
        sc = safe_rl.scores([r for r in records if r.task.scenario == scenario])
        compliant = np.isnan(ref["compliance"]) or sc["compliance"] >= ref["compliance"] - 1e-9
        n += int(sc["collisions"] <= ref["collisions"] and bool(compliant))
    return n


def mean_cost(records: list[Any]) -> float:
    """Mean episode cost (``info["cost"]`` summed over an episode) from the records' metrics.

    A collision, each violated obligation and each near-miss step (`EpisodeResult.serious_conflict_time`
    divided by the step length), as `crossing_env.safety.step_costs` counts them.
    """
    costs = [
        int(bool(r.result["collision"]))
        + r.result["yield_violations"]
        + round(r.result["serious_conflict_time"] * r.result["steps"] / r.result["duration"])
        for r in records
    ]
    return float(np.mean(costs))


def checkpoints(
    runs: Path, seeds: tuple[int, ...], scenarios: list[str], episodes: int, workers: int
) -> dict[str, Any]:
    """Greedy scores of every checkpoint of every run, and `yielding`'s on the same episodes."""
    ref_records = safe_rl._evaluate(["yielding"], scenarios, episodes, safe_rl.SELECTION_SEED, workers)
    reference = {s: safe_rl.scores([r for r in ref_records if r.task.scenario == s]) for s in scenarios}
    out: dict[str, Any] = {"yielding": {**safe_rl.scores(ref_records), "cost": mean_cost(ref_records)}}
    out["budgets"] = {}
    for budget in BUDGETS:
        per_seed = {}
        for seed in seeds:
            folder = run_folder(runs, budget, seed)
            steps = sorted(int(p.name.split("_")[1].split(".")[0]) for p in folder.glob("step_*.policy.npz"))
            rows = {}
            for n in steps:
                spec = f"mlp:{(folder / f'step_{n}.policy.npz').resolve()}"
                records = safe_rl._evaluate([spec], scenarios, episodes, safe_rl.SELECTION_SEED, workers)
                rows[str(n)] = {
                    **safe_rl.scores(records),
                    "cost": mean_cost(records),
                    "scenarios_at_yielding": _at_yielding(records, reference),
                }
            per_seed[str(seed)] = rows
        out["budgets"][f"{budget:g}"] = per_seed
    return out


def plot(rows: list[dict[str, Any]], greedy: dict[str, Any], seeds: tuple[int, ...], png: Path) -> None:
    """Top: training curves; bottom: greedy checkpoints and λ.

    One colour per budget: the mean over seeds thick (with its clipped band on the training curves), each
    seed thin.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    thousands = FuncFormatter(lambda x, _pos: f"{x / 1000:.0f}k")
    colours = dict(zip(BUDGETS, ("tab:blue", "tab:red"), strict=False))
    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5))
    titles = {"cost": "episode cost (budgets dotted)", "collision": "collision rate",
              "compliance": "yield compliance", "censored_delay": "censored delay (s)"}  # fmt: skip
    for ax, m in zip(axes[0], titles, strict=True):
        lo, hi = safe_rl.RANGES.get(m, (-np.inf, np.inf))
        for budget in BUDGETS:
            pts = [r for r in rows if r["metric"] == m and r["budget"] == budget]
            x = np.array([p["x"] for p in pts])
            for s in seeds:
                ax.plot(x, [p[f"seed_{s}"] for p in pts], lw=0.7, alpha=0.5, color=colours[budget])
            ax.plot(x, [p["mean"] for p in pts], "-o", ms=3, lw=2, color=colours[budget],
                    label=f"budget {budget:g}: mean over seeds")  # fmt: skip
            band = np.clip([[p["low"] for p in pts], [p["high"] for p in pts]], lo, hi)
            ax.fill_between(x, band[0], band[1], color=colours[budget], alpha=0.12)
            if m == "cost":
                ax.axhline(budget, ls=":", color=colours[budget])
        ax.set_title(f"training: {titles[m]}")
        ax.set_xlabel("env steps of PPO")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    ref = greedy["yielding"]
    greedy_panels = (("collisions", "greedy: collisions"), ("compliance", "greedy: yield compliance"),
                     ("censored_delay", "greedy: censored delay (s)"))  # fmt: skip
    for ax, (key, title) in zip(axes[1, :3], greedy_panels, strict=True):
        for budget in BUDGETS:
            per_seed = greedy["budgets"][f"{budget:g}"]
            steps = sorted({n for s in per_seed.values() for n in s}, key=int)
            for s in seeds:
                pts = per_seed[str(s)]
                ax.plot([int(n) for n in steps if n in pts], [pts[n][key] for n in steps if n in pts],
                        lw=0.7, alpha=0.5, marker=".", color=colours[budget])  # fmt: skip
            mean = [
                np.mean([per_seed[str(s)][n][key] for s in seeds if n in per_seed[str(s)]]) for n in steps
            ]
            ax.plot(
                [int(n) for n in steps],
                mean,
                "-o",
                ms=3,
                lw=2,
                color=colours[budget],
                label=f"budget {budget:g}",
            )
        ax.axhline(ref[key], ls="--", color="grey", label="yielding")
        ax.set_title(f"{title}, {ref['episodes']} episodes")
        ax.set_xlabel("env steps of PPO (0 = the warm start)")
        ax.grid(alpha=0.3)
    axes[1, 0].legend(fontsize=8)
    ax = axes[1, 3]
    for budget in BUDGETS:
        pts = [r for r in rows if r["metric"] == "multiplier" and r["budget"] == budget]
        for s in seeds:
            ax.plot([p["x"] for p in pts], [p[f"seed_{s}"] for p in pts], color=colours[budget], lw=1)
    ax.set_title("Lagrange multiplier λ (each seed, budgets' colours)")
    ax.set_xlabel("env steps of PPO")
    ax.grid(alpha=0.3)
    for ax in axes.flat:
        ax.xaxis.set_major_formatter(thousands)
    fig.suptitle(
        f"PPO-Lagrangian, {LONG_TIMESTEPS:,} steps, {len(seeds)} seeds per budget: training episodes"
        " (exploration on; band: 95 % t-interval across seeds, clipped to the metric's range) and greedy"
        " checkpoints"
    )
    fig.tight_layout()
    fig.savefig(png, dpi=80)
    plt.close(fig)


def replot(figures: Path, results: Path) -> None:
    """Draw ``rl_lagrangian_long.png`` again from the measured CSV and results JSON (no episodes run)."""
    rows = safe_rl.read_curve_rows(figures / "rl_lagrangian_long.csv", text=("metric",))
    data = json.loads(results.read_text(encoding="utf-8"))
    plot(rows, data["checkpoints"], tuple(data["seeds"]), figures / "rl_lagrangian_long.png")


def analyse(runs: Path, figures: Path, episodes: int, workers: int) -> dict[str, Any]:
    """Training curves, greedy checkpoints and the figure (see the module docstring)."""
    from scenarios import list_scenarios

    seeds = safe_rl.SEEDS
    scenarios = sorted(list_scenarios())
    rows = training_curves(runs, seeds)
    figures.mkdir(parents=True, exist_ok=True)
    with (figures / "rl_lagrangian_long.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    greedy = checkpoints(runs, seeds, scenarios, episodes, workers)
    plot(rows, greedy, seeds, figures / "rl_lagrangian_long.png")
    runs_info: dict[str, Any] = {}
    for budget in BUDGETS:
        for s in seeds:
            ep = safe_rl._read_episodes(run_folder(runs, budget, s) / "episodes.csv")
            last = ep["step"] > ep["step"].max() - 20_000
            runs_info[f"{budget:g}/{s}"] = {
                "train_wall_s": float(ep["wall_s"].max()),
                "final_multiplier": float(ep["multiplier"][-1]),
                "last_20k_cost": float(ep["cost"][last].mean()),
                "last_20k_collision_rate": float(ep["collision"][last].mean()),
            }
    return {
        "recipe": {f"{b:g}": recipe(b) for b in BUDGETS},
        "seeds": list(seeds),
        "budgets": [f"{b:g}" for b in BUDGETS],
        "timesteps": LONG_TIMESTEPS,
        "episodes_per_scenario": episodes,
        "scenarios": len(scenarios),
        "checkpoints": greedy,
        "runs": runs_info,
    }


def _cell(c: dict[str, Any] | None) -> str:
    if c is None:
        return "-"
    return (
        f"{c['collisions']} / {safe_rl._fmt(c['compliance'])} / {safe_rl._fmt(c['censored_delay'], 1)}"
        f" / {c['cost']:.2f} / {c['scenarios_at_yielding']}"
    )


def render_body(data: dict[str, Any]) -> str:
    """The markdown block of a results JSON (rendered into ``docs/rl.md``)."""
    greedy = data["checkpoints"]
    seeds = [str(s) for s in data["seeds"]]
    ref = greedy["yielding"]
    n_sc = data["scenarios"]
    lines = [
        f"PPO-Lagrangian trained {data['timesteps']:,} PPO steps (after the same warm start),"
        f" {len(seeds)} seeds per cost budget. Greedy checkpoints on {ref['episodes']} selection episodes"
        f" ({data['episodes_per_scenario']} per scenario, seed {safe_rl.SELECTION_SEED}), beside `yielding`"
        " on the same episodes; each cell: collisions / yield compliance / censored delay s / mean episode"
        f" cost / scenarios (of {n_sc}) as safe as `yielding` there (no more collisions, at least its"
        " compliance).",
        "",
        "| budget | PPO steps | " + " | ".join(f"seed {s}" for s in seeds) + " |",
        "|---|---|" + "---|" * len(seeds),
        f"| - | `yielding` | {_cell({**ref, 'scenarios_at_yielding': n_sc})} |" + " |" * (len(seeds) - 1),
    ]
    for budget in data["budgets"]:
        per_seed = greedy["budgets"][budget]
        steps = sorted({n for s in seeds for n in per_seed[s]}, key=int)
        for n in steps:
            cells = " | ".join(_cell(per_seed[s].get(n)) for s in seeds)
            lines.append(f"| {budget} | {int(n):,} | {cells} |")
    lines += [
        "",
        "The training episodes of the last 20,000 steps (exploration on) and the end of each run; wall-clock"
        " of the PPO phase (runs that train side by side share the machine's CPUs, so it says how long a"
        " run took in that measurement, not what one run alone costs):",
        "",
        "| budget | seed | episode cost | collision rate | λ at the end | wall-clock s |",
        "|---|---|---|---|---|---|",
    ]
    for budget in data["budgets"]:
        for s in seeds:
            r = data["runs"][f"{budget}/{s}"]
            lines.append(
                f"| {budget} | {s} | {r['last_20k_cost']:.2f} | {r['last_20k_collision_rate']:.3f} |"
                f" {r['final_multiplier']:.2f} | {r['train_wall_s']:.0f} |"
            )
    lines += ["", "![PPO-Lagrangian trained longer, at two budgets](rl_lagrangian_long.png)"]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Train (unless --no-train), analyse, write the results JSON."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=Path, default=Path("runs/safe_rl_long"), help="folder of the training runs")
    p.add_argument("--figures", type=Path, default=REPO / "docs", help="where rl_lagrangian_long.csv/png go")
    p.add_argument("--no-train", action="store_true", help="analyse finished runs only")
    p.add_argument("--episodes", type=int, default=8, help="greedy episodes per scenario and checkpoint")
    p.add_argument("--workers", type=int, default=2, help="evaluation worker processes")
    p.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "safe_rl_long_measured.json")
    p.add_argument(
        "--replot",
        type=Path,
        metavar="RESULTS_JSON",
        help="only draw the figure again from rl_lagrangian_long.csv in --figures and this results JSON",
    )
    a = p.parse_args(argv)
    if a.replot:
        replot(a.figures, a.replot)
        return 0
    times = {} if a.no_train else train(a.runs, safe_rl.SEEDS)
    t0 = time.perf_counter()
    result = analyse(a.runs, a.figures, a.episodes, a.workers)
    result["new_training_wall_s"] = times
    result["analysis_wall_s"] = round(time.perf_counter() - t0, 1)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    print(render_body(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
