"""`crossing-eval`: evaluate driving policies on the crossing scenarios with safety and efficiency metrics.

With no arguments it runs every built-in scenario x a fixed seed set x every policy in `agents.POLICIES`
(predictor wrappers on for the policies that use them), prints a table, and writes the files listed in
`crossing_eval.outputs` into the output folder (default ``./crossing-eval-results``). The numbers are
identical whatever ``--workers`` or ``--backend`` (see `crossing_eval.tasks`).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from crossing_common.cli import int_at_least
from crossing_eval.outputs import write_outputs
from crossing_eval.plugins import (
    PREDICTOR_NAMES,
    default_policies,
    policies_help,
    policy_spec,
    predictor_spec,
)
from crossing_eval.report import format_table, summarise
from crossing_eval.runners import default_workers, run_tasks
from crossing_eval.tasks import EpisodeRecord, make_tasks
from scenarios import list_scenarios

DEFAULT_EPISODES = 5
"""Episodes per (scenario, policy) in the default run: 8 scenarios x 5 seeds x 6 policies = 240 episodes."""
DEFAULT_SEED = 2024
"""Base seed of the default run."""
DEFAULT_OUT = "crossing-eval-results"
"""Default output folder (relative to the working directory)."""
PREDICTOR_CHOICES = PREDICTOR_NAMES
INTENTION_CHOICES = ("qlb", "classical", "none")


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
        help=policies_help(),
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
        type=_predictor,
        default="s-cgru",
        help="trajectory predictor wrapper for policies that use predictions: "
        f"{', '.join(PREDICTOR_CHOICES)} or a checkpoint file (default s-cgru)",
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
    args.scenarios = _resolve_scenarios(parser, args.scenarios)
    args.policies = _resolve_policies(parser, args.policies)
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
        "predictors_used": sorted({p for r in records for p in r.predictors}),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `crossing-eval`; returns the exit status (0 ok, 2 bad arguments)."""
    args = _parse(build_parser(), argv)
    tasks = make_tasks(
        args.scenarios, args.policies, args.episodes, args.seed, args.predictor, args.intention
    )
    print(
        f"crossing-eval: {len(args.scenarios)} scenario(s) x {len(args.policies)} policies"
        f" x {args.episodes} episode(s) = {len(tasks)} episodes, {args.workers} worker(s),"
        f" backend {args.backend}",
        file=sys.stderr,
    )
    t0 = time.perf_counter()
    records = run_tasks(tasks, args.workers, args.backend, args.address, show_progress=not args.no_progress)
    wall = time.perf_counter() - t0
    summary = summarise(records)
    files = write_outputs(records, summary, _settings(args, records), args.out)
    print(format_table(summary, args.policies))
    print(
        f"\n{len(records)} episodes in {wall:.1f} s ({len(records) / max(wall, 1e-9):.2f} episodes/s);"
        f" wrote {', '.join(files[:5])} and {len(files) - 5} worst-episode log(s) to {args.out}/"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
