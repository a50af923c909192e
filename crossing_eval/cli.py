"""`crossing-eval`: evaluate driving policies on the crossing scenarios with safety and efficiency metrics.

With no arguments it runs every built-in scenario x a fixed seed set x every policy in `agents.POLICIES`
(predictor wrappers on for the policies that use them), prints a table, and writes the files listed in
`crossing_eval.outputs` into the output folder (default: a new dated folder per run under
``./crossing-eval-results``, ``latest`` pointing at the newest; ``--out`` names one exactly). The numbers are
identical whatever ``--workers`` or ``--backend`` (see `crossing_eval.tasks`).
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import textwrap
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.sb3 import ModelFileError
from crossing_common.cli import DefaultsHelpFormatter, int_at_least, positive_float
from crossing_common.folders import OutputFolderError, StagedFolder
from crossing_common.runs import LATEST, claim_run_folder, point_latest, release_if_empty
from crossing_env.observation import PEDESTRIANS_KEY, PedestrianColumn
from crossing_eval.grid import GRID_MARKER, make_grid_tasks, parse_grid, write_grid_outputs
from crossing_eval.listing import ListAction
from crossing_eval.ncap import format_ncap_table, ncap_rows
from crossing_eval.outputs import import_plotting, write_outputs
from crossing_eval.plugins import (
    PREDICTOR_NAMES,
    default_policies,
    intention_spec,
    policies_help,
    policy_spec,
    predictor_spec,
)
from crossing_eval.provenance import run_provenance
from crossing_eval.report import scenario_labels
from crossing_eval.runners import (
    DEFAULT_RAY_TIMEOUT,
    EpisodeFailed,
    RayConnectionError,
    RunInterrupted,
    default_workers,
    pool_pays_off,
    pool_start_method,
    run_tasks,
)
from crossing_eval.scoring import REFERENCE_POLICY, reference_tasks
from crossing_eval.summary import HEADLINE_COLUMNS, HEADLINE_WIDTH, TABLE_COLUMNS, format_table, summarise
from crossing_eval.tasks import EpisodeRecord, EpisodeTask, cached_env, make_tasks
from predictors.forecast import ForecastError
from rollout import build_policy, checked_action, make_env
from rollout.wrappers import (
    DEFAULT_INTENTION,
    DEFAULT_PREDICTOR,
    WrapperError,
    intention_names,
    plugin_target,
)
from scenarios import ScenarioError, available_scenarios, list_scenarios, load_scenario

DEFAULT_EPISODES = 5
"""Episodes per (scenario, policy) in the default run: 12 scenarios x 5 seeds x 7 policies = 420 episodes."""
MAX_EPISODES = 10_000
"""Bound on ``--episodes``: the records of a run stay in memory until the tables are written."""
DEFAULT_SEED = 2024
"""Base seed of the default run."""
DEFAULT_OUT = "crossing-eval-results"
"""Default output folder (relative to the working directory)."""
DEFAULT_GRID_OUT = "crossing-eval-grid"
"""Default output folder of a `--grid` run (its own, so a grid never meets a plain run's folder)."""
PREDICTOR_CHOICES = PREDICTOR_NAMES
INTENTION_CHOICES = intention_names()
"""`rollout.wrappers.INTENTION_WRAPPERS` and 'none'; 'oracle' is privileged (an upper bound)."""
GRID_POLICIES = ("yielding", "predictive_yielding")
"""Policies of a `--grid` run unless `--policies` says otherwise."""


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _episodes(text: str) -> int:
    value = int_at_least(1)(text)
    if value > MAX_EPISODES:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_EPISODES:,} episodes, got {text!r}")
    return value


def _names(text: str) -> list[str]:
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of names, got {text!r}")
    return items


def build_parser() -> argparse.ArgumentParser:
    """The `crossing-eval` argument parser."""
    parser = argparse.ArgumentParser(
        prog="crossing-eval",
        description="Evaluate driving policies on crossing scenarios (safety and efficiency metrics)."
        " `crossing-eval compare DIR_A DIR_B` prints the differences between two runs.",
        formatter_class=DefaultsHelpFormatter,
    )
    parser.add_argument(
        "--list",
        action=ListAction,
        help="list every scenario, policy, predictor and intention model with one line each, and exit",
    )
    parser.add_argument(
        "--scenarios",
        type=_names,
        default=None,
        help="comma-separated built-in names or scenario .toml files (default: all built-in). Built-in:"
        f" {', '.join(available_scenarios())} (--list describes each)",
    )
    parser.add_argument(
        "--policies",
        type=_names,
        default=None,
        help=policies_help(),
    )
    parser.add_argument(
        "--episodes",
        type=_episodes,
        default=DEFAULT_EPISODES,
        help=f"episodes (seeds) per scenario and policy, at most {MAX_EPISODES:,} (every episode's record,"
        " a few kB, is kept in memory until the tables are written)",
    )
    parser.add_argument("--seed", type=_int, default=DEFAULT_SEED, help="base seed")
    parser.add_argument(
        "--workers",
        type=int_at_least(1),
        default=default_workers(),
        help="parallel worker processes (local) or CPUs for a fresh local Ray (default: the CPUs available)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help=f"output folder, used exactly and replaced whole at the end of the run (an earlier run's folder"
        f" or an empty one); default: a new dated folder per run under {DEFAULT_OUT}/ (or {DEFAULT_GRID_OUT}/"
        f" with --grid), with {LATEST} pointing at the newest, so no run replaces another",
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
        "--ray-timeout",
        type=positive_float,
        default=DEFAULT_RAY_TIMEOUT,
        help="seconds to wait for the Ray cluster at --address before giving up",
    )
    parser.add_argument(
        "--predictor",
        type=_predictor,
        default=DEFAULT_PREDICTOR,
        help="trajectory predictor wrapper for policies that use predictions: "
        f"{', '.join(PREDICTOR_CHOICES)}, oracle-noise=sigma (the oracle with an error of sigma m at 4.8 s),"
        " a checkpoint file, or your own forecaster: pkg.module:attr (a module in the current folder is"
        " found) or an entry point of the group crossing_env.predictors",
    )
    parser.add_argument(
        "--intention",
        type=_intention,
        default=DEFAULT_INTENTION,
        help="crossing-intention wrapper for policies that use predictions: "
        f"{', '.join(INTENTION_CHOICES)}, oracle-flip=q (the oracle wrong for a share q of pedestrians),"
        " or your own intent forecaster: pkg.module:attr or an entry point of crossing_env.predictors",
    )
    parser.add_argument(
        "--grid",
        nargs="+",
        default=None,
        metavar="AXIS=A,B",
        help="value-of-prediction grid: run every combination of e.g. intention=none,classical,qlb,oracle"
        " predictor=none,cvm,s-cgru,oracle on the same seeds and write value_of_prediction.md/.csv/.png"
        " (default policies: yielding,predictive_yielding)",
    )
    parser.add_argument(
        "--reveal-scenario",
        action="store_true",
        help="tell policies the whole scenario (its name, pedestrians, traffic, conflict) when they are"
        " built; by default they are evaluated blind, told only the road, the crossing and their car"
        " (docs/evaluation.md, 'What a policy may know')",
    )
    parser.add_argument(
        "--full-table",
        action="store_true",
        help="print every column (collisions, TTC, PET, DRAC, hard brakes, speeding...), not the headline"
        " table; both are written to the output folder (table.txt, table_full.txt, report.md)",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    return parser


def _resolve_scenarios(parser: argparse.ArgumentParser, names: list[str] | None) -> list[str]:
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


def _intention(text: str) -> str:
    try:
        return intention_spec(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _predictor(text: str) -> str:
    try:
        return predictor_spec(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _resolve_policies(parser: argparse.ArgumentParser, names: list[str] | None) -> list[str]:
    if names is None:
        policies, note = default_policies()
        if note:
            print(f"crossing-eval: {note}", file=sys.stderr)
        return policies
    out = []
    for name in names:
        try:
            out.append(policy_spec(name))
        except ValueError as exc:
            parser.error(f"argument --policies: {exc}")
    return list(dict.fromkeys(out))


def _parse(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> argparse.Namespace:
    """Parsed and checked arguments, with ``scenarios`` and ``policies`` resolved; bad ones exit with 2."""
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    args.scenarios = _resolve_scenarios(parser, args.scenarios)
    if args.grid is not None:
        try:
            args.grid = parse_grid(args.grid, INTENTION_CHOICES, PREDICTOR_CHOICES)
        except ValueError as exc:
            parser.error(f"argument --grid: {exc}")
        if args.policies is None:
            args.policies = list(GRID_POLICIES)
    args.policies = _resolve_policies(parser, args.policies)
    args.keep_runs = args.out is None  # the default: each run its own dated folder under the parent
    if args.out is None:
        args.out = Path(DEFAULT_GRID_OUT if args.grid is not None else DEFAULT_OUT)
    if args.address is not None and args.backend != "ray":
        parser.error(f"argument --address: {args.address!r} needs --backend ray")
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"argument --out: {str(args.out)!r} exists and is not a folder")
    if args.backend == "ray":
        # Imported here, not at the top: ray is an optional extra and slow to import; fail before running.
        try:
            import ray  # noqa: F401
        except ImportError:
            parser.error(
                "argument --backend: 'ray' needs the optional extra: pip install 'crossing-env[ray]'"
            )
    return args


def _settings(args: argparse.Namespace, records: Sequence[EpisodeRecord]) -> dict[str, Any]:
    """The settings stored in ``results.json``: what determines the numbers, never timing or workers."""
    return {
        "scenarios": args.scenarios,
        "policies": args.policies,
        "episodes": args.episodes,
        "seed": args.seed,
        "predictor": args.predictor,
        "intention": args.intention,
        "blind": not args.reveal_scenario,
        "predictors_used": sorted({p for r in records for p in r.predictors}),
        "provenance": run_provenance(args, records),
    }


def _fail(message: str) -> int:
    """One clear line on stderr and exit status 2 (bad input or an unusable setting; no traceback)."""
    print(f"crossing-eval: error: {message}", file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `crossing-eval`; returns the exit status (0 ok, 2 bad arguments or input)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["compare"]:
        from crossing_eval.compare import main as compare_main

        return compare_main(argv[1:])
    args = _parse(build_parser(), argv)
    # Every scenario file is read and validated before the first episode (and before any worker starts).
    try:
        for name in args.scenarios:
            load_scenario(name)
        labels = scenario_labels(args.scenarios)
    except ScenarioError as exc:
        return _fail(str(exc))
    tasks = _tasks(args)
    if args.grid is None:
        tasks += reference_tasks(tasks)  # the careful driver on every seed: the score's progress gate
    try:
        _preflight(args, tasks)
    except (WrapperError, ModelFileError, ValueError, TypeError, OSError) as exc:
        return _fail(str(exc))
    if args.keep_runs:
        try:
            args.out = claim_run_folder(args.out)
        except OSError as exc:
            return _fail(f"output folder {str(args.out)!r}: {exc.strerror or exc}")
    try:
        try:
            staged = StagedFolder(
                args.out,
                marker=GRID_MARKER if args.grid is not None else "results.json",
                tool="crossing-eval",
            )
        except OutputFolderError as exc:
            return _fail(f"argument --out: {exc}")
        try:
            code = _run(args, labels, staged, tasks)
        finally:
            staged.discard()  # a no-op after a commit; drops half-written output on any error or Ctrl-C
    finally:
        if args.keep_runs:
            release_if_empty(args.out)  # the run failed before writing: no empty dated folder left
    if getattr(args, "exit_now", False):  # Ray's own threads may still retry a connection: do not wait
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def console_main() -> None:
    """The `crossing-eval` command: `main`, then exit without the interpreter's last garbage collection.

    By the end of a run this process holds the kernels, models and envs: sweeping them at exit took about
    half a second, a tenth of a smoke run. `gc.freeze` takes them out of that sweep, which only looks for
    reference cycles to free in a process about to end; the outputs are written and closed before.
    """
    code = main()
    gc.freeze()
    sys.exit(code)


def _tasks(args: argparse.Namespace) -> list[EpisodeTask]:
    """The episodes of a plain run or of a `--grid`."""
    if args.grid is not None:
        return make_grid_tasks(args.scenarios, args.policies, args.episodes, args.seed, args.grid)
    return make_tasks(
        args.scenarios,
        args.policies,
        args.episodes,
        args.seed,
        args.predictor,
        args.intention,
        blind=not args.reveal_scenario,
    )


def _preflight(args: argparse.Namespace, tasks: Sequence[EpisodeTask]) -> None:
    """Build every wrapper combination and every policy once, here, before any worker starts.

    A predictor, a policy plug-in or a model file that cannot be loaded then stops the run with one line
    (exit 2) before the first episode, instead of failing in every worker.
    """
    # The envs are kept in this process's cache (`crossing_eval.tasks.cached_env`): a run small enough to
    # stay in this process (see `in_process`) starts its first episode with them, models already loaded.
    scenario = args.scenarios[0]
    combos = sorted({(t.intention, t.predictor) for t in tasks})
    for intention, predictor in combos:
        cached_env(scenario, intention=intention, predictor=predictor)
    # The trials run on fresh envs (one per combination): the cached ones stay as the episodes find them.
    wrappers = {t.policy: (t.intention, t.predictor) for t in reversed(tasks)}  # each policy's first
    envs: dict[tuple[str, str], Any] = {}
    try:
        for combo in combos:
            if plugin_target(combo[0]) or plugin_target(combo[1]):
                envs[combo] = make_env(scenario, *combo)[0]
                _try_plugins(envs[combo], combo, args.seed)
        for policy in args.policies:
            if wrappers[policy] not in envs:
                envs[wrappers[policy]] = make_env(scenario, *wrappers[policy])[0]
            _try_policy(policy, envs[wrappers[policy]], args.seed, blind=not args.reveal_scenario)
    finally:
        for env in envs.values():
            env.close()


def _try_policy(policy: str, env: Any, seed: int, *, blind: bool) -> None:
    """Build `policy`, reset it and ask it for its first action on `env`, as an episode would.

    Any error, a ``sys.exit()`` included, becomes one line naming the policy and the call that failed.

    Raises:
        PolicyTrialError: the policy cannot be built, reset or asked, or its first action is not one.
    """
    call = "building it"
    try:
        built = build_policy(policy, env, blind=blind)
        call = f"reset(seed={seed})"
        built.reset(seed=seed)
        obs, _ = env.reset(seed=seed)
        call = "its first action"
        checked_action(built(obs))
    except WrapperError:
        raise
    except SystemExit as exc:
        raise PolicyTrialError(f"policy {policy!r}: {call} called sys.exit({exc.code!r})") from None
    except Exception as exc:
        what = "cannot be built" if call == "building it" else f"{call} failed"
        raise PolicyTrialError(f"policy {policy!r} {what}: {type(exc).__name__}: {exc}") from exc


class PolicyTrialError(ValueError):
    """A policy that failed its trial before the first episode (one line naming it and the call)."""


PLUGIN_TRIAL_STEPS = 100
"""Steps (10 s) the preflight runs plug-in predictors for, stopping at the first pedestrian they forecast."""


def _try_plugins(env: Any, names: tuple[str, str], seed: int) -> None:
    """Run `env` under plug-in predictors until they have forecast a pedestrian (at most 10 s).

    A plug-in that raises or returns a malformed forecast is caught here, before the first episode.

    Raises:
        WrapperError: the plug-in raised or returned a malformed forecast (one line naming it).
    """
    plugins = " and ".join(n for n in names if plugin_target(n))
    try:
        obs, _ = env.reset(seed=seed)
        for _ in range(PLUGIN_TRIAL_STEPS):
            if (obs[PEDESTRIANS_KEY][:, PedestrianColumn.PRESENCE] > 0.5).any():
                break
            obs, _, terminated, truncated, _ = env.step(
                np.zeros(env.action_space.shape, env.action_space.dtype)
            )
            if terminated or truncated:
                break
    except Exception as exc:  # the plug-in's code: any error becomes one line naming it
        raise WrapperError(f"predictor {plugins}: {type(exc).__name__}: {exc}") from exc


def _run(
    args: argparse.Namespace, labels: dict[str, str], staged: StagedFolder, tasks: Sequence[EpisodeTask]
) -> int:
    """Run the tasks of a plain run or a `--grid` (the same checks, staging, errors and timeouts)."""
    if args.grid is not None:
        prefix = f"crossing-eval --grid: {len(args.grid.combinations())} combination(s) x "
    else:
        prefix = "crossing-eval: "
    workers = args.workers
    where = f"{workers} worker(s)"
    if args.backend == "local" and workers > 1:
        method = pool_start_method()
        if pool_pays_off(len(tasks), workers, method):
            where = f"{workers} worker(s) ({method})"
        else:
            workers, where = 1, "in this process (fewer episodes than a worker pool's start-up is worth)"
    extra = sum(t.policy not in args.policies for t in tasks)
    reference = f" + {extra} of the reference driver ({REFERENCE_POLICY}, for the score)" if extra else ""
    print(
        f"{prefix}{len(args.scenarios)} scenario(s) x"
        f" {len(args.policies)} policies x {args.episodes} episode(s) = {len(tasks) - extra} episodes"
        f"{reference}, {where}, backend {args.backend}",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    try:
        records = run_tasks(
            tasks,
            workers,
            args.backend,
            args.address,
            show_progress=not args.no_progress,
            ray_timeout=args.ray_timeout,
            while_waiting=import_plotting,
        )
    except RayConnectionError as exc:
        args.exit_now = exc.abandoned
        return _fail(str(exc))
    except (ScenarioError, EpisodeFailed, WrapperError, ForecastError, ModelFileError) as exc:
        # WrapperError: a predictor that cannot be loaded (missing module, corrupt or tampered weights);
        # ForecastError: a (plug-in) predictor's malformed forecast in an episode.
        return _fail(str(exc))
    except RunInterrupted as exc:  # SIGINT / SIGTERM: workers stopped, the previous output untouched
        print(f"crossing-eval: {exc}", file=sys.stderr)
        return exc.exit_code
    wall = time.perf_counter() - t0
    if args.grid is not None:
        table, files = write_grid_outputs(records, args, staged.path)
        where = _commit(args, staged)
        print(table)
        print(f"{len(records)} episodes in {wall:.1f} s; wrote {', '.join(files)} to {where}")
        return 0
    ran = len(records)
    references = [r for r in records if r.task.policy not in args.policies]
    records = [r for r in records if r.task.policy in args.policies]
    summary = summarise(records, references)
    settings = _settings(args, records)
    settings["scenario_names"] = labels
    files = write_outputs(records, summary, settings, staged.path, references)
    where = _commit(args, staged)
    print(format_table(summary, args.policies, TABLE_COLUMNS if args.full_table else HEADLINE_COLUMNS))
    ncap = ncap_rows(records)
    if ncap:
        print("\n" + _fit(format_ncap_table(ncap)))
    worst = sum(f.startswith("worst/") for f in files)
    done = (
        f"{ran} episodes in {wall:.1f} s ({ran / max(wall, 1e-9):.2f} episodes/s); wrote"
        f" {', '.join(f for f in files if not f.startswith('worst/') and f != 'table_full.txt')},"
        f" table_full.txt (every column) and {worst} worst-episode log(s) to {where}"
    )
    print("\n" + _fit(done))
    return 0


def _fit(text: str) -> str:
    """`text` with each line longer than `HEADLINE_WIDTH` wrapped (notes; table rows are narrower)."""
    return "\n".join(
        textwrap.fill(line, HEADLINE_WIDTH, break_long_words=False, break_on_hyphens=False)
        if len(line) > HEADLINE_WIDTH
        else line
        for line in text.splitlines()
    )


def _commit(args: argparse.Namespace, staged: StagedFolder) -> str:
    """Swap the outputs in; with kept runs point ``latest`` at this one. Returns where they are (to print)."""
    staged.commit()
    if not args.keep_runs:
        return f"{args.out}/"
    note = point_latest(args.out)
    if note:
        print(f"crossing-eval: {note}", file=sys.stderr)
        return f"{args.out}/"
    return f"{args.out}/ ({args.out.parent / LATEST} points at it)"


if __name__ == "__main__":
    console_main()
