"""`crossing-eval`: evaluate driving policies on the crossing scenarios with safety and efficiency metrics.

With no arguments it runs every built-in scenario x a fixed seed set x every policy in `agents.POLICIES`
(predictor wrappers on for the policies that use them), prints a table, and writes into the output
folder (default ``./crossing-eval-results``):

- ``results.json``: the settings, a summary per policy, per (scenario, policy) and overall, and every
  episode's metrics (`crossing_env.metrics.EpisodeResult.as_dict`);
- ``episodes.csv`` (one row per episode) and ``summary.csv`` (one row per policy and "overall");
- ``safety_vs_efficiency.png`` and ``min_ttc.png`` (matplotlib, Agg backend);
- ``worst/*.json``: episode logs of the worst episodes (collisions first, then lowest min TTC; the five
  worst overall plus the worst of every other policy) that ``crossing-replay episode`` re-runs.

Determinism: the seed of an episode depends only on (``--seed``, scenario name, episode index), via
`numpy.random.SeedSequence`, so every policy meets the same situations (a paired comparison; the policy
is deliberately not part of the seed) and the numbers are identical whatever ``--workers`` or
``--backend``: results are sorted by (scenario, policy, episode) before anything is written, and the JSON
holds no timing or worker information.
"""

from __future__ import annotations

import argparse
import csv
import inspect
import io
import json
import math
import multiprocessing
import os
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crossing_env.cli import int_at_least
from crossing_env.files import write_bytes_atomic

DEFAULT_EPISODES = 5
"""Episodes per (scenario, policy) in the default run: 8 scenarios x 5 seeds x 5 policies = 200 episodes."""
DEFAULT_SEED = 2024
"""Base seed of the default run."""
DEFAULT_OUT = "crossing-eval-results"
"""Default output folder (relative to the working directory)."""
WORST_EPISODES = 5
"""Number of worst episodes saved as replayable logs."""
PREDICTOR_CHOICES = ("s-cgru", "cvm", "none")
INTENTION_CHOICES = ("qlb", "classical", "none")


# ---------------------------------------------------------------------------------------------------------
# Tasks and records
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EpisodeTask:
    """One episode to run: everything a worker process (or Ray task) needs, picklable."""

    scenario: str
    """Built-in scenario name or path to a scenario file."""
    policy: str
    """Name from `agents.POLICIES`."""
    episode: int
    """Episode index within (scenario, policy)."""
    seed: int
    """Seed given to `env.reset`."""
    predictor: str = "none"
    """Trajectory predictor wrapper ('s-cgru', 'cvm' or 'none'); only for policies that use predictors."""
    intention: str = "none"
    """Intention wrapper ('qlb', 'classical' or 'none'); only for policies that use predictors."""


@dataclass
class EpisodeRecord:
    """What a task returns: the metrics plus what is needed to replay the episode."""

    task: EpisodeTask
    """The task that produced it."""
    result: dict[str, Any]
    """`EpisodeResult.as_dict()` (JSON-safe)."""
    actions: list[float]
    """Actions given to `env.step`, for the replay log."""
    predictors: list[str]
    """Wrappers actually used (empty if none or unavailable)."""
    final_ground_truth: Any = None
    """Last `GroundTruth` of the episode (lets the replay verify itself)."""

    @property
    def key(self) -> tuple[str, str, int]:
        """Sort key: (scenario, policy, episode)."""
        return self.task.scenario, self.task.policy, self.task.episode


def episode_seed(base_seed: int, scenario: str, episode: int) -> int:
    """Deterministic 32-bit seed of (base seed, scenario, episode); independent of policy and workers."""
    tag = zlib.crc32(Path(scenario).stem.encode("utf-8")) if scenario else 0
    ss = np.random.SeedSequence([int(base_seed) & 0xFFFFFFFF, tag, int(episode)])
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def make_tasks(
    scenarios: Sequence[str],
    policies: Sequence[str],
    episodes: int,
    base_seed: int,
    predictor: str = "s-cgru",
    intention: str = "qlb",
) -> list[EpisodeTask]:
    """The sorted task list of a run; predictor settings only go to policies that use them."""
    from agents.policies import policy_uses_predictors

    tasks = []
    for sc in scenarios:
        for pol in policies:
            uses = policy_uses_predictors(pol)
            for ep in range(episodes):
                tasks.append(
                    EpisodeTask(
                        scenario=sc,
                        policy=pol,
                        episode=ep,
                        seed=episode_seed(base_seed, sc, ep),
                        predictor=predictor if uses else "none",
                        intention=intention if uses else "none",
                    )
                )
    return sorted(tasks, key=lambda t: (t.scenario, t.policy, t.episode))


# ---------------------------------------------------------------------------------------------------------
# Running episodes (in this process, a worker process or a Ray task)
# ---------------------------------------------------------------------------------------------------------

_ENV_CACHE: dict[tuple[str, str, str], tuple[Any, list[str]]] = {}
_WARNED: set[str] = set()


def _warn_once(message: str) -> None:
    if message not in _WARNED:
        _WARNED.add(message)
        print(f"crossing-eval: {message}", file=sys.stderr)


def build_env(scenario: str, predictor: str = "none", intention: str = "none") -> tuple[Any, list[str]]:
    """The env for a scenario with the requested wrappers.

    Missing predictor modules are skipped with a message; the record then lists which wrappers were used.
    """
    import gymnasium as gym

    import crossing_env

    env = gym.make(crossing_env.ENV_ID, scenario=scenario)
    used: list[str] = []
    if intention != "none":
        try:
            from predictors import intention as intention_mod
        except ImportError as exc:
            _warn_once(f"intention wrapper unavailable ({exc}); running without crossing_intention")
        else:
            cls_name = "QLBIntention" if intention == "qlb" else "ClassicalIntention"
            cls = getattr(intention_mod, cls_name, None)
            if cls is None:
                _warn_once(f"predictors.intention has no {cls_name}; running without crossing_intention")
            else:
                env = cls(env)
                used.append(f"intention:{intention}")
    if predictor != "none":
        try:
            from predictors.trajectory_wrapper import TrajectoryPrediction
        except ImportError as exc:
            _warn_once(f"trajectory wrapper unavailable ({exc}); running without predicted_paths")
        else:
            try:
                env = TrajectoryPrediction(env, model=predictor)
                used.append(f"trajectory:{predictor}")
            except (OSError, ValueError, RuntimeError) as exc:
                _warn_once(f"trajectory predictor {predictor!r} failed to load ({exc}); running without it")
    return env, used


def _cached_env(task: EpisodeTask) -> tuple[Any, list[str]]:
    key = (task.scenario, task.predictor, task.intention)
    if key not in _ENV_CACHE:
        _ENV_CACHE[key] = build_env(task.scenario, task.predictor, task.intention)
    return _ENV_CACHE[key]


def run_episode(task: EpisodeTask) -> EpisodeRecord:
    """Run one episode with a fresh policy; same task, same record (in any process)."""
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover - torch is a hard dependency
        pass
    from agents.policies import make_policy
    from crossing_env.metrics import EpisodeMetrics

    env, used = _cached_env(task)
    base = env.unwrapped
    policy = make_policy(task.policy, scenario=base.scenario, dt=base.config.dt)
    obs, info = env.reset(seed=task.seed)
    metrics = EpisodeMetrics(base.scenario, base.config.dt)
    actions: list[float] = []
    done = False
    gt = info["ground_truth"]
    while not done:
        action = np.asarray(policy(obs), dtype=np.float32).reshape(1)
        actions.append(float(action[0]))
        obs, _, terminated, truncated, info = env.step(action)
        gt = info["ground_truth"]
        metrics.update(gt)
        done = terminated or truncated
    return EpisodeRecord(
        task=task, result=metrics.result().as_dict(), actions=actions, predictors=used, final_ground_truth=gt
    )


def _run_local(
    tasks: Sequence[EpisodeTask], workers: int, progress: Callable[[], None]
) -> list[EpisodeRecord]:
    if workers <= 1:
        out = []
        for t in tasks:
            out.append(run_episode(t))
            progress()
        return out
    records: list[EpisodeRecord] = []
    # forkserver, not fork: a forked child of a process that has run torch ops can hang in torch's
    # thread pool, and the predictor wrappers run torch.
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=multiprocessing.get_context("forkserver")
    ) as pool:
        futures = [pool.submit(run_episode, t) for t in tasks]
        for fut in as_completed(futures):
            records.append(fut.result())
            progress()
    return records


def _run_ray(
    tasks: Sequence[EpisodeTask], address: str | None, workers: int, progress: Callable[[], None]
) -> list[EpisodeRecord]:
    """Run the tasks as Ray tasks on an existing cluster (`address`) or a fresh local one."""
    try:
        import ray
    except ImportError as exc:
        raise SystemExit(
            f"crossing-eval: --backend ray needs the optional extra: pip install 'crossing-env[ray]' ({exc})"
        ) from exc
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address in (None, "", "local"):
            # A fresh instance we start ourselves: every Ray process inherits these, so token auth and
            # usage stats stay off consistently (see docs/scale-and-rl.md); users may override them.
            os.environ.setdefault("RAY_AUTH_MODE", "disabled")
            os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
            kwargs.update(address="local", num_cpus=max(1, workers), object_store_memory=100 * 2**20)
        else:
            kwargs["address"] = address
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1)(run_episode)
        pending = [remote.remote(t) for t in tasks]
        records: list[EpisodeRecord] = []
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            records.extend(ray.get(done))
            progress()
        return records
    finally:
        if started:
            ray.shutdown()


def run_tasks(
    tasks: Sequence[EpisodeTask],
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
    show_progress: bool = True,
) -> list[EpisodeRecord]:
    """Run every task and return the records sorted by (scenario, policy, episode)."""
    from tqdm import tqdm

    bar = tqdm(total=len(tasks), desc="episodes", unit="ep", disable=not show_progress, file=sys.stderr)
    try:
        if backend == "ray":
            records = _run_ray(tasks, address, workers, bar.update)
        else:
            records = _run_local(tasks, workers, bar.update)
    finally:
        bar.close()
    return sorted(records, key=lambda r: r.key)


# ---------------------------------------------------------------------------------------------------------
# Summaries and output
# ---------------------------------------------------------------------------------------------------------

TABLE_COLUMNS = (
    ("policy", "policy"),
    ("n", "episodes"),
    ("collision rate [95% CI]", None),
    ("minTTC p5/p50 s", None),
    ("PET p5 s", "pet_pedestrian_first_p5"),
    ("DRAC mean", "drac_crossing_mean"),
    ("hard brakes/ep", "hard_brakes_per_episode"),
    ("yield compl. (n)", None),
    ("mean delay s", "mean_delay"),
    ("pass rate", "pass_rate"),
)

CSV_EPISODE_FIELDS = (
    "scenario",
    "policy",
    "episode",
    "seed",
    "collision",
    "pedestrian_collisions",
    "vehicle_collisions",
    "max_impact_speed",
    "min_ttc",
    "min_separation",
    "min_pet_pedestrian_first",
    "min_pet_ego_first",
    "max_drac_crossing",
    "hard_braking_events",
    "max_deceleration",
    "yield_obligations",
    "yield_compliant",
    "yield_violations",
    "passed_crossing",
    "delay",
    "time_to_pass",
    "distance_travelled",
    "duration",
)


def summarise(records: Sequence[EpisodeRecord]) -> dict[str, Any]:
    """Per policy, per (scenario, policy) and overall aggregates (`crossing_env.metrics.aggregate`)."""
    from crossing_env.metrics import EpisodeResult, aggregate

    results = [EpisodeResult.from_dict(r.result) for r in records]
    by_policy: dict[str, list[Any]] = {}
    by_pair: dict[str, list[Any]] = {}
    for rec, res in zip(records, results, strict=True):
        by_policy.setdefault(rec.task.policy, []).append(res)
        by_pair.setdefault(f"{rec.task.scenario}/{rec.task.policy}", []).append(res)
    return {
        "per_policy": {k: aggregate(v) for k, v in by_policy.items()},
        "per_scenario_policy": {k: aggregate(v) for k, v in sorted(by_pair.items())},
        "overall": aggregate(results),
    }


def _fmt(x: Any, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    if isinstance(x, float):
        return f"{x:.{digits}f}"
    return str(x)


def format_table(summary: dict[str, Any], policies: Sequence[str]) -> str:
    """Fixed-width text table: one row per policy plus 'overall'."""
    rows = [[c for c, _ in TABLE_COLUMNS]]
    entries = [(p, summary["per_policy"][p]) for p in policies if p in summary["per_policy"]]
    entries.append(("overall", summary["overall"]))
    for name, agg in entries:
        lo, hi = agg["collision_ci95"]
        comp = agg["yield_compliance"]
        rows.append(
            [
                name,
                str(agg["episodes"]),
                f"{agg['collision_rate']:.3f} [{lo:.3f}, {hi:.3f}]",
                f"{_fmt(agg['min_ttc_p5'])}/{_fmt(agg['min_ttc_p50'])}",
                _fmt(agg["pet_pedestrian_first_p5"]),
                _fmt(agg["drac_crossing_mean"]),
                _fmt(agg["hard_brakes_per_episode"]),
                f"{_fmt(comp, 3)} ({agg['yield_obligations']})",
                _fmt(agg["mean_delay"]),
                _fmt(agg["pass_rate"]),
            ]
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for i, row in enumerate(rows):
        lines.append(
            "  ".join(
                cell.ljust(w) if j == 0 else cell.rjust(w)
                for j, (cell, w) in enumerate(zip(row, widths, strict=True))
            )
        )
        if i == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _csv_text(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()


def _plot(
    records: Sequence[EpisodeRecord], summary: dict[str, Any], policies: Sequence[str], out: Path
) -> None:
    """Safety-vs-efficiency scatter and min-TTC distributions as PNG (written atomically)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [p for p in policies if p in summary["per_policy"]]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name in names:
        agg = summary["per_policy"][name]
        lo, hi = agg["collision_ci95"]
        rate = agg["collision_rate"]
        delay = agg["mean_delay"]
        x = 0.0 if delay is None or math.isnan(delay) else delay
        ax.errorbar(x, rate, yerr=[[rate - lo], [hi - rate]], fmt="o", capsize=4, label=name)
        ax.annotate(name, (x, rate), textcoords="offset points", xytext=(6, 6), fontsize=8)
    ax.set_xlabel("mean delay at the crossing (s)  → less efficient")
    ax.set_ylabel("collision rate (95% Wilson CI)  → less safe")
    ax.set_title("Safety vs efficiency per policy")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save_fig(fig, out / "safety_vs_efficiency.png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    cap = 10.0
    bins = np.linspace(0.0, cap, 21)
    for name in names:
        vals = np.array(
            [
                r.result["min_ttc"] if r.result["min_ttc"] is not None else np.inf
                for r in records
                if r.task.policy == name
            ],
            dtype=np.float64,
        )
        ax.hist(np.minimum(vals, cap), bins=bins, histtype="step", linewidth=1.5, label=name)
    ax.axvline(1.5, color="red", linestyle="--", linewidth=1, label="serious conflict (1.5 s)")
    ax.set_xlabel(f"episode minimum TTC to a pedestrian (s; ≥ {cap:g} and 'never' in the last bin)")
    ax.set_ylabel("episodes")
    ax.set_title("Minimum TTC distribution per policy")
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save_fig(fig, out / "min_ttc.png")
    plt.close(fig)


def _save_fig(fig: Any, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    write_bytes_atomic(path, buf.getvalue())


def worst_records(records: Sequence[EpisodeRecord], n: int = WORST_EPISODES) -> list[EpisodeRecord]:
    """The `n` worst episodes overall, then the worst of each policy not yet included.

    Ranking: collisions first (highest impact speed first), then the lowest min TTC; ties by key.
    Episodes with neither a collision nor a finite TTC are never "worst".
    """

    def badness(r: EpisodeRecord) -> tuple[int, float, float, tuple[str, str, int]]:
        res = r.result
        impact = res["max_impact_speed"] if res["max_impact_speed"] is not None else 0.0
        ttc = res["min_ttc"] if res["min_ttc"] is not None else math.inf
        return (0 if res["collision"] else 1, -impact, ttc, r.key)

    ranked = [
        r for r in sorted(records, key=badness) if r.result["collision"] or r.result["min_ttc"] is not None
    ]
    chosen = ranked[:n]
    for rec in ranked:
        if all(c.task.policy != rec.task.policy for c in chosen):
            chosen.append(rec)
    return chosen


def save_worst(records: Sequence[EpisodeRecord], out: Path, n: int = WORST_EPISODES) -> list[str]:
    """Write replayable logs of the worst episodes into ``out/worst``; returns the file names."""
    folder = out / "worst"
    names = []
    for rank, rec in enumerate(worst_records(records, n)):
        t = rec.task
        name = f"{rank:02d}_{Path(t.scenario).stem}_{t.policy}_ep{t.episode}.json"
        meta = {"rank": rank, "episode": t.episode, "metrics": rec.result, "predictors": rec.predictors}
        predictor = t.predictor if f"trajectory:{t.predictor}" in rec.predictors else None
        intention = t.intention if f"intention:{t.intention}" in rec.predictors else None
        try:
            from crossing_env.replay import save_episode_log
        except ImportError:
            payload = {
                "format": "crossing-env-episode-log",
                "version": 1,
                "scenario": t.scenario,
                "seed": t.seed,
                "policy": t.policy,
                "predictor": predictor,
                "intention": intention,
                "actions": rec.actions,
                "metadata": meta,
            }
            write_bytes_atomic(folder / name, json.dumps(payload, indent=1).encode("utf-8"))
        else:
            folder.mkdir(parents=True, exist_ok=True)
            extra = (
                {"intention": intention}
                if "intention" in inspect.signature(save_episode_log).parameters
                else {}
            )
            save_episode_log(
                folder / name,
                scenario=t.scenario,
                seed=t.seed,
                actions=np.asarray(rec.actions, dtype=np.float32),
                policy=t.policy,
                predictor=predictor,
                final_ground_truth=rec.final_ground_truth,
                metadata=meta,
                **extra,
            )
        names.append(name)
    return names


def write_outputs(
    records: Sequence[EpisodeRecord], summary: dict[str, Any], settings: dict[str, Any], out: Path
) -> list[str]:
    """JSON, CSVs, plots and worst-episode logs; every file written atomically. Returns the file names."""
    from crossing_env.metrics import json_safe

    out.mkdir(parents=True, exist_ok=True)
    policies = settings["policies"]
    doc = {
        "settings": settings,
        "summary": json_safe(summary),
        "episodes": [
            {
                "scenario": r.task.scenario,
                "policy": r.task.policy,
                "episode": r.task.episode,
                "seed": r.task.seed,
                "predictors": r.predictors,
                "metrics": r.result,
            }
            for r in records
        ],
    }
    write_bytes_atomic(
        out / "results.json", (json.dumps(doc, indent=1, sort_keys=True) + "\n").encode("utf-8")
    )

    rows = []
    for r in records:
        res = r.result
        rows.append(
            [
                r.task.scenario,
                r.task.policy,
                r.task.episode,
                r.task.seed,
                *(_csv_value(res[f]) for f in CSV_EPISODE_FIELDS[4:]),
            ]
        )
    write_bytes_atomic(out / "episodes.csv", _csv_text(CSV_EPISODE_FIELDS, rows).encode("utf-8"))

    keys = [k for k in summary["overall"] if not isinstance(summary["overall"][k], tuple | list)]
    srows = []
    for name, agg in [
        *((p, summary["per_policy"][p]) for p in policies if p in summary["per_policy"]),
        ("overall", summary["overall"]),
    ]:
        lo, hi = agg["collision_ci95"]
        srows.append([name, *(_csv_value(agg[k]) for k in keys), _csv_value(lo), _csv_value(hi)])
    header = ["policy", *keys, "collision_ci95_low", "collision_ci95_high"]
    write_bytes_atomic(out / "summary.csv", _csv_text(header, srows).encode("utf-8"))

    _plot(records, summary, policies, out)
    worst = save_worst(records, out)
    return [
        "results.json",
        "episodes.csv",
        "summary.csv",
        "safety_vs_efficiency.png",
        "min_ttc.png",
        *(f"worst/{w}" for w in worst),
    ]


def _csv_value(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if x is None:
        return ""
    return x


# ---------------------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------------------


def default_workers() -> int:
    """CPUs this process may use (results do not depend on it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _names(text: str) -> list[str]:
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of names, got {text!r}")
    return items


def build_parser() -> argparse.ArgumentParser:
    """The `crossing-eval` argument parser."""
    parser = argparse.ArgumentParser(
        prog="crossing-eval",
        description="Evaluate driving policies on crossing scenarios (safety and efficiency metrics).",
    )
    parser.add_argument(
        "--scenarios",
        type=_names,
        default=None,
        help="comma-separated built-in names or scenario files (default: all built-in)",
    )
    parser.add_argument(
        "--policies",
        type=_names,
        default=None,
        help="comma-separated policy names (default: all): see agents.POLICIES",
    )
    parser.add_argument(
        "--episodes",
        type=int_at_least(1),
        default=DEFAULT_EPISODES,
        help=f"episodes (seeds) per scenario and policy (default {DEFAULT_EPISODES})",
    )
    parser.add_argument("--seed", type=_int, default=DEFAULT_SEED, help=f"base seed (default {DEFAULT_SEED})")
    parser.add_argument(
        "--workers",
        type=int_at_least(1),
        default=default_workers(),
        help="parallel worker processes (local) or CPUs for a fresh local Ray"
        f" (default: the CPUs available, here {default_workers()})",
    )
    parser.add_argument(
        "--out", type=Path, default=Path(DEFAULT_OUT), help=f"output folder (default ./{DEFAULT_OUT})"
    )
    parser.add_argument(
        "--backend",
        choices=("local", "ray"),
        default="local",
        help="run episodes in local processes or as Ray tasks (needs the 'ray' extra)",
    )
    parser.add_argument(
        "--address",
        default=None,
        help="Ray cluster address ('auto', 'host:port', 'ray://host:10001'; the cluster's Python needs"
        " crossing-env installed); default: a fresh local Ray",
    )
    parser.add_argument(
        "--predictor",
        choices=PREDICTOR_CHOICES,
        default="s-cgru",
        help="trajectory predictor wrapper for policies that use predictions (default s-cgru)",
    )
    parser.add_argument(
        "--intention",
        choices=INTENTION_CHOICES,
        default="qlb",
        help="crossing-intention wrapper for policies that use predictions (default qlb)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def _resolve_scenarios(parser: argparse.ArgumentParser, names: list[str] | None) -> list[str]:
    from scenarios import list_scenarios

    builtin = list(list_scenarios())
    if names is None:
        return sorted(builtin)
    out = []
    for name in names:
        if name in builtin or (name.endswith(".toml") and Path(name).is_file()):
            out.append(name)
        else:
            parser.error(
                f"argument --scenarios: unknown scenario {name!r} (not built-in and not an existing"
                f" .toml file); built-in: {', '.join(sorted(builtin))}"
            )
    return sorted(dict.fromkeys(out))


def _resolve_policies(parser: argparse.ArgumentParser, names: list[str] | None) -> list[str]:
    from agents.policies import POLICIES

    if names is None:
        return list(POLICIES)
    for name in names:
        if name not in POLICIES:
            parser.error(f"argument --policies: unknown policy {name!r}; choose from {', '.join(POLICIES)}")
    return [p for p in POLICIES if p in names]


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `crossing-eval`; returns the exit status (0 ok, 2 bad arguments)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    scenarios = _resolve_scenarios(parser, args.scenarios)
    policies = _resolve_policies(parser, args.policies)
    if args.address is not None and args.backend != "ray":
        parser.error(f"argument --address: {args.address!r} needs --backend ray")
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"argument --out: {str(args.out)!r} exists and is not a folder")
    if args.backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            parser.error(
                "argument --backend: 'ray' needs the optional extra: pip install 'crossing-env[ray]'"
            )

    tasks = make_tasks(scenarios, policies, args.episodes, args.seed, args.predictor, args.intention)
    print(
        f"crossing-eval: {len(scenarios)} scenario(s) x {len(policies)} policies x {args.episodes} episode(s)"
        f" = {len(tasks)} episodes, {args.workers} worker(s), backend {args.backend}",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    records = run_tasks(tasks, args.workers, args.backend, args.address, show_progress=not args.no_progress)
    wall = time.perf_counter() - t0
    summary = summarise(records)
    settings = {
        "scenarios": scenarios,
        "policies": policies,
        "episodes": args.episodes,
        "seed": args.seed,
        "predictor": args.predictor,
        "intention": args.intention,
        "predictors_used": sorted({p for r in records for p in r.predictors}),
    }
    files = write_outputs(records, summary, settings, args.out)
    print(format_table(summary, policies))
    print(
        f"\n{len(records)} episodes in {wall:.1f} s ({len(records) / max(wall, 1e-9):.2f} episodes/s);"
        f" wrote {', '.join(files[:5])} and {len(files) - 5} worst-episode log(s) to {args.out}/"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
