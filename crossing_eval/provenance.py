"""Where a run's numbers came from: package version, commit, the files that were loaded, the settings.

Stored under ``provenance`` in ``results.json`` (and beside a grid's table), so a table can be traced to
the code and the exact model files behind it. Apart from the command line as typed, nothing here depends on
timing, workers or the backend: the recorded command leaves out the options that only say how to run
(`RUN_ONLY_OPTIONS`), so ``results.json`` is byte-identical whatever ran the episodes.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from rollout import TRAJECTORY_WRAPPERS
from rollout.wrappers import plugin_target
from scenarios import load_scenario

REPO = Path(__file__).resolve().parents[1]
RUN_ONLY_OPTIONS = {"--workers": 1, "--backend": 1, "--address": 1, "--ray-timeout": 1, "--out": 1}
"""Options (with their value count) that change how a run executes, never its numbers."""
FLAGS_RUN_ONLY = ("--no-progress",)


def numbers_command(argv: Sequence[str]) -> list[str]:
    """`argv` without the run-only options (``--workers 2``, ``--out=dir``, ``--no-progress``, ...)."""
    out: list[str] = []
    skip = 0
    for arg in argv:
        if skip:
            skip -= 1
            continue
        name = arg.split("=", 1)[0]
        if name in FLAGS_RUN_ONLY:
            continue
        if name in RUN_ONLY_OPTIONS:
            skip = 0 if "=" in arg else RUN_ONLY_OPTIONS[name]
            continue
        out.append(arg)
    return out


def package_version() -> str:
    """The installed crossing-env version ("unknown" when run from a tree that is not installed)."""
    try:
        return metadata.version("crossing-env")
    except metadata.PackageNotFoundError:
        return "unknown"


def source_commit() -> str:
    """The checkout's commit, with ``-dirty`` when tracked files differ; "unknown" outside a git checkout."""
    if not (REPO / ".git").exists():
        return "unknown"
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=REPO,
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")


def _shown(path: Path) -> str:
    """A shipped file relative to the project (same on every machine); a user's file as given."""
    try:
        return path.resolve().relative_to(REPO).as_posix()
    except ValueError:
        return str(path)


def sha256(path: Path) -> str:
    """Hex sha256 of a file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def plugin_file(name: str) -> Path | None:
    """The source file of a plug-in predictor's module (imported by then), None for any other name."""
    target = plugin_target(name)
    module = sys.modules.get(target.partition(":")[0]) if target else None
    source = getattr(module, "__file__", None)
    return Path(source) if source else None


def model_files(policies: Sequence[str], predictors: Sequence[str]) -> list[Path]:
    """The weight and statistics files the run loaded (shipped or given by path), and plug-in sources."""
    files: list[Path] = []
    for name in predictors:
        if name in TRAJECTORY_WRAPPERS:
            model = TRAJECTORY_WRAPPERS[name].kwargs.get("model")
            if model and model != "cvm":
                from predictors.checkpoints import WEIGHTS_DIR

                files.append(WEIGHTS_DIR / f"{model}_all.pt")
        elif name != "none" and Path(name).is_file():
            files.append(Path(name))
        elif (source := plugin_file(name)) is not None:
            files.append(source)
    from agents.registry import SHIPPED_POLICIES

    for spec in policies:
        path: Path | None = None
        if spec in SHIPPED_POLICIES:
            path = SHIPPED_POLICIES[spec]  # one file: weights and statistics together
        elif spec.startswith("mlp:"):
            path = Path(spec[len("mlp:") :])
        elif spec.startswith("sb3:"):
            path = Path(spec[len("sb3:") :])
            from agents.sb3 import stats_path

            stats = stats_path(path)  # the statistics file the SB3 policy loads, if any
            if stats.is_file():
                files.append(stats)
        if path is not None and path.is_file():
            files.append(path)
    return list(dict.fromkeys(files))


def provenance(
    scenarios: Sequence[str], policies: Sequence[str], predictors: Sequence[str], argv: Sequence[str]
) -> dict[str, Any]:
    """The ``provenance`` block of ``results.json``."""
    return {
        "package_version": package_version(),
        "commit": source_commit(),
        "python": sys.version.split()[0],
        "command": " ".join(["crossing-eval", *numbers_command(argv)]),
        "scenario_durations": {s: load_scenario(s).duration for s in scenarios},
        "files": {_shown(p): sha256(p) for p in model_files(policies, predictors)},
    }


def run_provenance(args: Any, records: Sequence[Any]) -> dict[str, Any]:
    """`provenance` of a `crossing-eval` run (plain or grid) from its parsed arguments and its records."""
    labels = [label for record in records for label in record.predictors]
    return provenance(args.scenarios, args.policies, predictors_ran(labels), args.argv)


def predictors_ran(labels: Sequence[str]) -> list[str]:
    """Predictor names from labels such as ``trajectory:s-cgru`` or ``intention:qlb`` (what actually ran)."""
    return sorted({label.split(":", 1)[1] for label in labels})
