"""How fast a user gets a first result: the smoke run warm and cold, and the default table's episodes/s.

Each figure is the wall time of a fresh ``python -m crossing_eval.cli`` process (imports, preflight,
episodes, outputs), run the way a user runs it:

- warm smoke: ``crossing-eval --scenarios zebra_case1 --episodes 1`` with the numba cache already filled
  (one unmeasured run fills it first);
- cold smoke: the same with ``NUMBA_CACHE_DIR`` pointed at a new empty folder, so every kernel compiles
  as on a fresh install (the kernels are ``@njit(cache=True)``: by default the cache lies in
  ``__pycache__`` beside each module; ``NUMBA_CACHE_DIR`` moves it; Python's own ``.pyc`` files stay);
- the default table: ``crossing-eval`` with no arguments, its own "episodes/s" line (episodes over the
  time from the first submitted episode to the last record) and the process's wall time.

With ``--peer DIR`` every measurement also runs on the checkout in DIR (e.g. the commit before a change,
``git worktree add ../peer HEAD~1 --detach``), interleaved with this tree's, so both meet the same load;
the default tables of both are compared byte for byte (``table.txt``, ``episodes.csv``).

    python benchmarks/first_result.py [--repeats 3] [--cold-repeats 1] [--skip-default] [--peer DIR]
"""

from __future__ import annotations

import argparse
import filecmp
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
SMOKE = ["--scenarios", "zebra_case1", "--episodes", "1"]
WARM_TARGET_S = 4.0
COLD_TARGET_S = 20.0
BASELINE_EPISODES_PER_S = 5.5
"""The default table's speed when the first-result targets were set (315 episodes in 57-73 s, 2 workers)."""
RATE = re.compile(r"(\d+) episodes in ([\d.]+) s \(([\d.]+) episodes/s\)")


def run_cli(tree: Path, args: list[str], out: Path, numba_cache: Path | None = None) -> tuple[float, str]:
    """Wall seconds of one `crossing-eval` process on the checkout `tree`, and its stdout."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    if numba_cache is not None:
        env["NUMBA_CACHE_DIR"] = str(numba_cache)
    cmd = [sys.executable, "-m", "crossing_eval.cli", *args, "--no-progress", "--out", str(out)]
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=out.parent, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return wall, proc.stdout


def spread(values: list[float]) -> str:
    """``median [min-max]`` of a few wall times."""
    if len(values) == 1:
        return f"{values[0]:.1f}"
    return f"{statistics.median(values):.1f} [{min(values):.1f}-{max(values):.1f}]"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=3, help="warm smoke runs per tree")
    parser.add_argument("--cold-repeats", type=int, default=1, help="cold smoke runs per tree")
    parser.add_argument("--skip-default", action="store_true", help="skip the default table (minutes)")
    parser.add_argument("--peer", type=Path, default=None, help="another checkout measured interleaved")
    parser.add_argument(
        "--peer-warm-elsewhere",
        type=float,
        default=None,
        help="the peer's warm smoke (s) measured on another machine: scales the smoke runs to that machine",
    )
    args = parser.parse_args()
    if args.repeats < 1 or args.cold_repeats < 0:
        parser.error("--repeats must be >= 1 and --cold-repeats >= 0")
    trees = {"this tree": HERE}
    if args.peer is not None:
        if not (args.peer / "crossing_eval" / "cli.py").is_file():
            parser.error(f"--peer: {str(args.peer)!r} is not a crossing-env checkout")
        trees["peer"] = args.peer.resolve()
    warm: dict[str, list[float]] = {name: [] for name in trees}
    cold: dict[str, list[float]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory(prefix="first-result-") as tmp:
        root = Path(tmp)
        for tree in trees.values():  # fill each tree's numba cache (unmeasured)
            run_cli(tree, SMOKE, root / "fill")
        for i in range(args.repeats):
            for name, tree in trees.items():
                wall, _ = run_cli(tree, SMOKE, root / "warm")
                warm[name].append(wall)
                print(f"warm smoke {i + 1}/{args.repeats} ({name}): {wall:.1f} s", flush=True)
        for i in range(args.cold_repeats):
            for name, tree in trees.items():
                cache = Path(tempfile.mkdtemp(prefix="numba-", dir=root))
                wall, _ = run_cli(tree, SMOKE, root / "cold", numba_cache=cache)
                cold[name].append(wall)
                print(f"cold smoke {i + 1}/{args.cold_repeats} ({name}): {wall:.1f} s", flush=True)
        rates: dict[str, tuple[float, float]] = {}
        if not args.skip_default:
            for name, tree in trees.items():
                wall, stdout = run_cli(tree, [], root / f"default-{len(rates)}")
                match = RATE.search(stdout)
                rate = float(match.group(3)) if match else float("nan")
                rates[name] = (rate, wall)
                print(f"default table ({name}): {rate:.2f} episodes/s, process {wall:.1f} s", flush=True)
            if len(rates) == 2:
                same = all(
                    filecmp.cmp(root / "default-0" / f, root / "default-1" / f, shallow=False)
                    for f in ("table.txt", "episodes.csv")
                )
                verdict = "identical" if same else "DIFFER"
                print(f"default table.txt and episodes.csv of both trees: {verdict}")
    print("\nsummary (wall seconds: median [min-max]; the CPUs may be shared, compare within one run)")
    for name in trees:
        line = f"  {name:9s}  warm smoke {spread(warm[name])} s (target <= {WARM_TARGET_S:g})"
        if cold[name]:
            line += f"; cold smoke {spread(cold[name])} s (target <= {COLD_TARGET_S:g})"
        if name in rates:
            rate, wall = rates[name]
            line += (
                f"; default table {rate:.2f} episodes/s ({rate / BASELINE_EPISODES_PER_S:.2f}x the"
                f" {BASELINE_EPISODES_PER_S} measured when the targets were set), process {wall:.0f} s"
            )
        print(line)
    if "peer" in trees:
        ratios = [f"warm smoke {_ratio(warm)}"]
        if cold["peer"]:
            ratios.append(f"cold smoke {_ratio(cold)}")
        if len(rates) == 2:
            speed_up = rates["this tree"][0] / rates["peer"][0]
            ratios.append(
                f"default table {speed_up:.2f}x the peer's episodes/s (the target, with the code as it was"
                " when the targets were set as the peer: >= 2x)"
            )
        print(f"  this tree against the peer in the same run: {'; '.join(ratios)}")
        if args.peer_warm_elsewhere is not None:
            # The peer's code ran the same smoke there and here: its ratio is this machine's pace
            # today against that one's, and the seconds targets were set on that machine.
            pace = statistics.median(warm["peer"]) / args.peer_warm_elsewhere
            scaled = f"warm smoke {statistics.median(warm['this tree']) / pace:.1f} s"
            if cold["this tree"]:
                scaled += f", cold smoke {statistics.median(cold['this tree']) / pace:.1f} s"
            here = f"{pace:.2f}x slower" if pace >= 1 else f"{1 / pace:.2f}x faster"
            print(
                f"  scaled to the machine where the peer's warm smoke took {args.peer_warm_elsewhere:g} s"
                f" (this one ran it {here}): this tree's {scaled} (targets <= {WARM_TARGET_S:g} and"
                f" <= {COLD_TARGET_S:g} s)"
            )


def _ratio(times: dict[str, list[float]]) -> str:
    """This tree's median wall time as a fraction of the peer's (below 1: faster)."""
    return f"{statistics.median(times['this tree']) / statistics.median(times['peer']):.2f}x the peer's time"


if __name__ == "__main__":
    main()
