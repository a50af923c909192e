"""The registry of results: every registered table is measured by a named command into a committed JSON and
rendered from that JSON into the docs between markers, never typed by hand.

    python -m benchmarks.results                      # list the entries and whether each is stale
    python -m benchmarks.results default_table        # measure one entry (slow), write its JSON, render
    python -m benchmarks.results --render             # re-render every table from its JSON (fast)
    python -m benchmarks.results --check              # exit 1 if a rendered table differs from its JSON
    python -m benchmarks.results --stale              # regenerate every stale entry, cheapest first

Each JSON records the commit it was measured on, what the measurement cost (seconds) and a **fingerprint**
of what the entry shows. A small fixed-seed run through the same code path (every built-in scenario with two
policies, `fingerprint_records`) gives both parts of it: what the episodes *do* (actions, final states,
contacts) and the entry's own *figures* computed from those episodes by the code its numbers come from (the
default table's `format_table`, the discrimination report's cells, ...). Adding a field to the episode record
moves neither part, so no table goes stale for it; changing how a shown figure is computed moves exactly the
entries that show it. When the code's fingerprint no longer matches the JSON's, the table is rendered with a
marker saying that it must be regenerated (``--stale`` regenerates every such entry, cheapest first): a stale
table is never shown as current. An entry whose numbers do not come from simulated episodes carries its own
fingerprint instead (the predictor tables on recorded data: a hash of the shipped weights' manifest, the
social-force fit and a tiny fixed evaluation of every row), and two blocks may render one JSON (measured
once).
Rendered blocks sit between ``<!-- results:NAME -->`` and ``<!-- /results:NAME -->`` in a markdown file.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
RESULTS_DIR = REPO / "benchmarks" / "results"
FINGERPRINT_POLICIES = ("yielding", "constant_speed")
"""Policies of the behaviour fingerprint: one that yields (predictors on) and one that never brakes."""
FINGERPRINT_STEPS = 300
"""Steps per fingerprint episode (30 s): long enough that the yielding policy meets, waits at and passes the
crossing in every built-in scenario, so a change to its rules changes the hash."""


FINGERPRINT_BASE_SEED = 2024
"""Base seed of the fingerprint episodes (`crossing_eval.tasks.episode_seed`, episode 0 of each scenario)."""


@functools.cache
def fingerprint_records() -> tuple[Any, ...]:
    """The fingerprint episodes as `crossing-eval`'s records: every built-in scenario with each policy of
    `FINGERPRINT_POLICIES`, one fixed-seed episode of `FINGERPRINT_STEPS` steps each.

    They run through `rollout` (the path `crossing-eval` takes), so they change whenever a scenario file, the
    world, the predictors or a fingerprint policy change what an episode does.
    """
    from crossing_eval.tasks import EpisodeRecord, EpisodeTask, episode_seed
    from rollout import RolloutSpec, run_spec
    from scenarios import list_scenarios

    records = []
    for scenario in sorted(list_scenarios()):
        for policy in FINGERPRINT_POLICIES:
            seed = episode_seed(FINGERPRINT_BASE_SEED, scenario, 0)
            episode = run_spec(RolloutSpec(scenario=scenario, policy=policy), seed, FINGERPRINT_STEPS)
            records.append(
                EpisodeRecord(
                    task=EpisodeTask(scenario=scenario, policy=policy, episode=0, seed=seed),
                    result=episode.result,
                    actions=episode.actions,
                    predictors=[],
                    final_ground_truth=episode.final_ground_truth,
                    episode_return=episode.episode_return,
                    initial_speed=episode.initial_speed,
                )
            )
    return tuple(records)


def dynamics_digest(records: Sequence[Any]) -> str:
    """Hash of what the episodes do (`rollout.dynamics_digest` of each, with its scenario, policy and seed).

    No figure computed from an episode enters it (those are each entry's `Entry.figures`), so a field added
    to the episode record leaves it as it was.
    """
    from rollout import dynamics_digest as episode_digest

    digest = hashlib.sha256()
    for record in records:
        digest.update(f"{record.task.scenario}/{record.task.policy}/{record.task.seed}".encode())
        digest.update(episode_digest(record).encode())
    return digest.hexdigest()[:16]


def behaviour_fingerprint() -> str:
    """What the fingerprint episodes do (`dynamics_digest`): the listing's summary line."""
    return dynamics_digest(fingerprint_records())


LEARNED_FINGERPRINT_SCENARIOS = ("busy_zebra", "children_running", "zebra_case1")
"""Scenarios of the learned policies' fingerprint: zebras where the shield's limits act."""


@functools.cache
def learned_stamp() -> str:
    """The shipped learned policies: their files and what a short rollout of each does.

    The fingerprint episodes drive only the rule policies; a table with a learned row (the default table,
    the safe-RL tables) must also go stale when the weights, the shield or the numpy actor change.
    """
    from agents.registry import SHIPPED_POLICIES
    from crossing_eval.tasks import episode_seed
    from rollout import RolloutSpec, run_spec

    digest = hashlib.sha256()
    for name in sorted(SHIPPED_POLICIES):
        digest.update(SHIPPED_POLICIES[name].read_bytes())
        for scenario in LEARNED_FINGERPRINT_SCENARIOS:
            spec = RolloutSpec(scenario=scenario, policy=name)
            episode = run_spec(spec, episode_seed(FINGERPRINT_BASE_SEED, scenario, 0), FINGERPRINT_STEPS)
            digest.update(f"{scenario}/{name}".encode())
            digest.update(json.dumps(episode.actions).encode())
    return digest.hexdigest()[:16]


def intent_weights_stamp() -> str:
    """The intent weights file, for tables of `crossing-eval`'s default run.

    The default run's `predictive_yielding` reads QLB's calibration and release bound from that file; a new
    bound changes its row while neither rule policy of the fingerprint episodes moves.
    """
    from predictors.learned_intent_weights import WEIGHTS_PATH

    return hashlib.sha256(WEIGHTS_PATH.read_bytes()).hexdigest()[:16]


ADVERSARY_FINGERPRINT_SCENARIOS = ("busy_zebra", "ncap_cpna")
"""Scenarios of the adversaries' fingerprint: a crowded zebra and a pedestrian stepping out before the car."""


@functools.cache
def adversary_stamp() -> str:
    """What a short rollout of each shipped adversary does (`agents.adversaries.ADVERSARIES`).

    The fingerprint episodes drive `yielding` and `constant_speed` only; the adversary benchmark must also
    go stale when an adversary drives differently.
    """
    from agents.adversaries import ADVERSARIES
    from crossing_eval.tasks import episode_seed
    from rollout import RolloutSpec, dynamics_digest, run_spec

    digest = hashlib.sha256()
    for name in ADVERSARIES:
        for scenario in ADVERSARY_FINGERPRINT_SCENARIOS:
            spec = RolloutSpec(scenario=scenario, policy=name)
            episode = run_spec(spec, episode_seed(FINGERPRINT_BASE_SEED, scenario, 0), FINGERPRINT_STEPS)
            digest.update(f"{scenario}/{name}/{dynamics_digest(episode)}".encode())
    return digest.hexdigest()[:16]


def score_figures(records: Sequence[Any]) -> str:
    """Every fingerprint episode's score and terms (`crossing_eval.scoring`), `yielding` the reference."""
    from crossing_eval.scoring import attach_scores

    scored = [dataclasses.replace(r, score=None) for r in records]
    attach_scores(scored)
    return json.dumps({f"{r.task.scenario}/{r.task.policy}": r.score for r in scored}, sort_keys=True)


DEFAULT_RUN_STAMPS: tuple[Callable[[], str], ...] = (learned_stamp, intent_weights_stamp)
"""What a table of `crossing-eval`'s default run depends on beyond the fingerprint episodes."""


def table_figures(records: Sequence[Any]) -> str:
    """The printed table of `crossing-eval` (every column) computed on the fingerprint episodes."""
    from crossing_eval.summary import format_table, summarise

    return format_table(summarise(records), FINGERPRINT_POLICIES)


def discrimination_figures(records: Sequence[Any]) -> str:
    """The discrimination report's cells (`benchmarks.discrimination.cell`) of the fingerprint episodes."""
    from benchmarks.discrimination import cell
    from scenarios import load_scenario

    cells = {
        f"{r.task.scenario}/{r.task.policy}": cell([r], load_scenario(r.task.scenario).duration)
        for r in records
    }
    return json.dumps(cells, sort_keys=True, default=str)


def safe_rl_figures(records: Sequence[Any]) -> str:
    """The safe-RL study's scores (`studies.safe_rl.scores`) of each fingerprint policy's episodes."""
    from studies.safe_rl import scores

    by_policy = {p: scores([r for r in records if r.task.policy == p]) for p in FINGERPRINT_POLICIES}
    return json.dumps(by_policy, sort_keys=True, default=str)


def source_commit() -> str:
    """The checkout's commit (``-dirty`` when tracked files differ)."""
    from crossing_eval.provenance import source_commit as commit

    return commit()


# ---------------------------------------------------------------------------------------------------------
# Entries
# ---------------------------------------------------------------------------------------------------------


def _measure_default_table() -> dict[str, Any]:
    """`crossing-eval` with no arguments (2 workers): the printed table and the run's figures."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        proc = subprocess.run(
            [sys.executable, "-m", "crossing_eval.cli", "--out", str(out), "--no-progress", "--workers", "2"],
            capture_output=True,
            text=True,
            check=False,
        )
        if proc.returncode != 0:
            raise RuntimeError(f"crossing-eval failed ({proc.returncode}): {proc.stderr[-2000:]}")
        table = (out / "table_full.txt").read_text(encoding="utf-8")
        headline = (out / "table.txt").read_text(encoding="utf-8")
        settings = json.loads((out / "results.json").read_text(encoding="utf-8"))["settings"]
    episodes = len(settings["scenarios"]) * len(settings["policies"]) * settings["episodes"]
    return {"command": "crossing-eval", "table": table, "headline": headline, "episodes": episodes}


def _render_default_table(data: dict[str, Any], key: str = "table") -> str:
    what = "the full table, `--full-table`" if key == "table" else "the table it prints"
    return (
        f"Measured with `{data['command']}` (no arguments, {data['episodes']} episodes, 2 workers; {what})"
        f" on commit `{data['commit'][:12]}`;"
        " rendered from `benchmarks/results/default_table.json` by `python -m benchmarks.results`.\n\n"
        f"```\n{data.get(key, data['table']).rstrip()}\n```"
    )


def _render_default_headline(data: dict[str, Any]) -> str:
    return _render_default_table(data, "headline")


def _measure_discrimination() -> dict[str, Any]:
    """`benchmarks/discrimination.py --seeds 45` (it writes its own JSON)."""
    path = RESULTS_DIR / "discrimination.json"
    subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "discrimination.py"), "--seeds", "45", "--no-progress"],
        check=True,
        cwd=REPO,
    )
    return json.loads(path.read_text(encoding="utf-8"))


def _render_discrimination(data: dict[str, Any]) -> str:
    from benchmarks.discrimination import render_body

    return render_body(data)


def _measure_adversaries() -> dict[str, Any]:
    """`benchmarks/adversaries.py --episodes 20` (it writes its own JSON)."""
    subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "adversaries.py"), "--episodes", "20", "--no-progress"],
        check=True,
        cwd=REPO,
        stdout=subprocess.DEVNULL,
    )
    return json.loads((RESULTS_DIR / "adversaries.json").read_text(encoding="utf-8"))


def _render_adversaries(data: dict[str, Any]) -> str:
    from benchmarks.adversaries import render_body

    return render_body(data)


def _study_json(module: str, runs: str) -> dict[str, Any]:
    """Run ``python -m MODULE --runs runs/RUNS --out F`` (a study that keeps its runs and writes its JSON)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "result.json"
        cmd = [sys.executable, "-m", module, "--runs", str(REPO / "runs" / runs), "--out", str(out)]
        subprocess.run(cmd, check=True, cwd=REPO)
        return json.loads(out.read_text(encoding="utf-8"))


def _measure_safe_rl() -> dict[str, Any]:
    """`studies/safe_rl.py`: trains what is missing in ``runs/safe_rl`` (about 1 h per learner on 2 cores),
    then the curves, steps to safety, selection and the paired evaluation against `yielding`."""
    return _study_json("studies.safe_rl", "safe_rl")


def _render_safe_rl(data: dict[str, Any]) -> str:
    from studies.safe_rl import render_body

    return render_body(data)


def _render_safe_rl_summary(data: dict[str, Any]) -> str:
    from studies.safe_rl import render_summary

    return render_summary(data)


def _measure_safe_rl_long() -> dict[str, Any]:
    """`studies/safe_rl_long.py`: the Lagrangian learner trained longer (trains what is missing in
    ``runs/safe_rl_long``), its curves and greedy checkpoints."""
    return _study_json("studies.safe_rl_long", "safe_rl_long")


def _render_safe_rl_long(data: dict[str, Any]) -> str:
    from studies.safe_rl_long import render_body

    return render_body(data)


def _measure_predictors() -> dict[str, Any]:
    """Every trajectory predictor on ETH/UCY and SDD from the shipped weights (`studies.predictor_tables`)."""
    from studies.predictor_tables import measure

    return measure()


def _render_predictors(data: dict[str, Any]) -> str:
    from studies.predictor_tables import render_results

    return render_results(data)


def _render_predictors_summary(data: dict[str, Any]) -> str:
    from studies.predictor_tables import render_summary

    return render_summary(data)


def _measure_intention() -> dict[str, Any]:
    """`benchmarks/intention.py` at its defaults (12 episodes per world, seeds 1000..1011), in process."""
    from benchmarks.intention import evaluate

    return evaluate()


def _render_intention(data: dict[str, Any]) -> str:
    from benchmarks.intention import render_body

    return render_body(data)


def _measure_sim_transfer() -> dict[str, Any]:
    """`python -m studies.sim_transfer` with its defaults: the predictors on simulated pedestrians."""
    from predictors.data import default_data_root
    from studies.sim_transfer import measure

    start = time.perf_counter()
    data = measure(["busy_zebra", "zebra_case1"], 3, 0, default_data_root())
    data.update(command="python -m studies.sim_transfer", wall_seconds=round(time.perf_counter() - start, 1))
    return data


def _render_sim_transfer(data: dict[str, Any]) -> str:
    from studies.sim_transfer import render

    return (
        f"Measured with `{data['command']}` (defaults) on commit `{data['commit'][:12]}`,"
        f" {data['wall_seconds']:.0f} s; rendered from `benchmarks/results/sim_transfer.json` by"
        " `python -m benchmarks.results`.\n\n" + render(data)
    )


def _measure_value_of_prediction() -> dict[str, Any]:
    """`python -m studies.value_of_prediction` (defaults): runs the rows missing from ``runs/value_v2``
    (about 1.5 h on 2 cores from nothing), then the accuracy and the analysis."""
    return _study_json("studies.value_of_prediction", "value_v2")


def _render_value_of_prediction(data: dict[str, Any]) -> str:
    from crossing_eval.value_v2 import render_body

    return render_body(data)


def _render_value_of_prediction_summary(data: dict[str, Any]) -> str:
    from crossing_eval.value_v2 import render_summary

    return render_summary(data)


@functools.cache
def _value_fingerprint() -> str:
    from studies.value_of_prediction import value_fingerprint

    return value_fingerprint()


def _measure_predictor_checkpoints() -> dict[str, Any]:
    from studies.predictor_tables import measure_checkpoints

    return measure_checkpoints()


def _render_predictor_checkpoints(data: dict[str, Any]) -> str:
    from studies.predictor_tables import render_checkpoints

    return render_checkpoints(data)


def _script_report(script: str, *args: str) -> dict[str, Any]:
    """Run ``python benchmarks/SCRIPT ARGS`` and keep its printed report, wall time and the load it met.

    The machines here are shared, so the 1-minute load average at the start is kept beside a speed.
    """
    load = os.getloadavg()[0]
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / script), *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=REPO,
    )
    if proc.returncode != 0:
        raise RuntimeError(f"benchmarks/{script} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    data: dict[str, Any] = {
        "command": " ".join(["python", f"benchmarks/{script}", *args]),
        "output": proc.stdout,
        "wall_seconds": round(time.perf_counter() - start, 1),
        "load_average": round(load, 2),
    }
    if args:
        data["defaults"] = False
    return data


def _measure_predictor_speed() -> dict[str, Any]:
    """`python benchmarks/predictors.py` (defaults): its printed report of sizes and CPU times."""
    return _script_report("predictors.py")


def _script_block(data: dict[str, Any], name: str, timing: str) -> str:
    """A script's report as a code block, under the line that says how and where it was measured."""
    options = " (defaults)" if data.get("defaults", True) else ""
    load = f" load average {data['load_average']:.1f} at the start;" if "load_average" in data else ""
    return (
        f"Measured with `{data['command']}`{options} on commit `{data['commit'][:12]}`,{timing}{load}"
        f" rendered from `benchmarks/results/{name}.json` by `python -m benchmarks.results`.\n\n"
        f"```\n{data['output'].rstrip()}\n```"
    )


def _render_predictor_speed(data: dict[str, Any]) -> str:
    timing = (
        f" {data['wall_seconds']:.0f} s; CPU times depend on the machine and its load, the ratios much less;"
    )
    return _script_block(data, "predictor_speed", timing)


FIRST_RESULT_PEER = "7cf605a633c5f1195a36a2530e4f1fd810e4a808"
"""The code as it was when issue 26 was filed (its default table had fewer scenarios): `first_result` runs it
interleaved as the peer, so that the gain is measured against it in one run on the same machine (the
issue's 5.5 episodes/s was measured on another, busier one, and the machines' speed moves between runs)."""

FIRST_RESULT_PEER_WARM_S = 11.9
"""The peer's warm smoke run as issue 26 measured it on its machine, where its seconds targets were set:
`first_result` scales this tree's smoke times to that machine by the peer's time here."""


def _measure_first_result() -> dict[str, Any]:
    """`python benchmarks/first_result.py --peer DIR` (3 warm and 1 cold smoke run and the default table of
    this tree and of `FIRST_RESULT_PEER`, checked out into a temporary git worktree and removed after)."""
    with tempfile.TemporaryDirectory(prefix="first-result-peer-") as tmp:
        peer = Path(tmp) / "peer"
        git = ["git", "-C", str(REPO), "worktree"]
        add = [*git, "add", "--detach", str(peer), FIRST_RESULT_PEER]
        subprocess.run(add, check=True, capture_output=True)
        try:
            data = _script_report(
                "first_result.py", "--peer", str(peer), "--peer-warm-elsewhere", str(FIRST_RESULT_PEER_WARM_S)
            )
        finally:
            subprocess.run([*git, "remove", "--force", str(peer)], check=False, capture_output=True)
    data["command"] = (
        f"python benchmarks/first_result.py --peer <checkout of {FIRST_RESULT_PEER[:12]}>"
        f" --peer-warm-elsewhere {FIRST_RESULT_PEER_WARM_S:g}"
    )
    data["output"] = data["output"].replace(str(peer), "PEER")
    data["defaults"] = False
    return data


def _render_first_result(data: dict[str, Any]) -> str:
    timing = f" 2 cores, {data['wall_seconds']:.0f} s in all; wall times depend on the machine and its load;"
    return _script_block(data, "first_result", timing)


FIRST_RESULT_LINE = re.compile(
    r"this tree\s+warm smoke (?P<warm>[\d.]+) .*?cold smoke (?P<cold>[\d.]+) s.*?"
    r"default table (?P<rate>[\d.]+) episodes/s.*?process (?P<process>\d+) s"
)
"""This tree's figures in `benchmarks/first_result.py`'s summary (the README shows no other)."""


def _render_first_result_summary(data: dict[str, Any]) -> str:
    found = FIRST_RESULT_LINE.search(data["output"])
    if found is None:
        raise ValueError("first_result.json: its output has no summary line for this tree")
    f = found.groupdict()
    return (
        f"On a 2-core machine (commit `{data['commit'][:12]}`; measured by `python -m benchmarks.results"
        " first_result`, details in [docs/benchmarks.md](docs/benchmarks.md)):\n\n"
        f"```\nquick first result (the command above)   {f['warm']} s; {f['cold']} s the first time after"
        " installing (numba compiles its kernels once)\n"
        f"main job (crossing-eval, no arguments)   {f['process']} s ({f['rate']} episodes/s)\n```"
    )


BENCHMARK_SCRIPTS: dict[str, tuple[str, tuple[str, ...], str]] = {
    "env_throughput": ("env_throughput.py", (), "speed"),
    "env_throughput_wrappers": ("env_throughput.py", ("--wrappers",), "speed"),
    "scaling": ("scaling.py", (), "speed"),
    "eval_throughput": ("eval_throughput.py", ("--episodes", "1"), "workers"),
    "soak": ("soak.py", ("--scenario", "default"), "memory"),
    "world_health": ("world_health.py", (), "counts"),
    "oracle_cost": ("oracle_cost.py", ("--seeds", "2"), "speed"),
}
"""Entry name → (script in ``benchmarks/``, its options as ``docs/benchmarks.md`` documents them, what it
reports: speeds against a peer, speeds by worker count, memory or counts)."""

_SCRIPT_TIMING = {
    "speed": " 2 cores, {wall:.0f} s; speeds depend on the machine and its load, the ratios to the peer"
    " timed in the same run much less;",
    "workers": " 2 cores, {wall:.0f} s; episodes/s depend on the machine and its load, and a second worker"
    " helps only as far as a second core is free;",
    "memory": " {wall:.0f} s; resident memory depends on the platform's libraries;",
    "counts": " {wall:.0f} s;",
}
"""What the line above a script's report says about its figures, per kind."""


def _render_script(data: dict[str, Any], name: str) -> str:
    kind = BENCHMARK_SCRIPTS[name][2]
    return _script_block(data, name, _SCRIPT_TIMING[kind].format(wall=data["wall_seconds"]))


WORLD_PROXY = ("busy_zebra", "zebra_case1")
"""Built-in scenarios whose fingerprint episodes stand for worlds that are not built-in scenarios (the
default road, synthetic crowds): a change to the world or the pedestrians shows in them."""


def _script_entry(
    name: str,
    tier: str,
    scenarios: tuple[str, ...] | None,
    stamps: tuple[Callable[[], str], ...] = (),
) -> Entry:
    """A benchmark script of ``docs/benchmarks.md`` run with its documented options, its report in a block."""
    script, args, _ = BENCHMARK_SCRIPTS[name]
    return Entry(
        name,
        tier,
        functools.partial(_script_report, script, *args),
        functools.partial(_render_script, name=name),
        REPO / "docs" / "benchmarks.md",
        scenarios=scenarios,
        stamps=stamps,
    )


PREDICTOR_COMPARE_RUNS = (("s-cgru", ()), ("cvm", ("--predictor", "cvm")))
"""The two runs of the `crossing-eval compare` example: output folder → the options beside
``--policies yielding``."""


def _crossing_eval(args: list[str], cwd: Path) -> str:
    proc = subprocess.run(
        [sys.executable, "-m", "crossing_eval.cli", *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=cwd,
    )
    if proc.returncode != 0:
        raise RuntimeError(
            f"crossing-eval {' '.join(args)} failed ({proc.returncode}): {proc.stderr[-2000:]}"
        )
    return proc.stdout


def _measure_predictor_compare() -> dict[str, Any]:
    """`crossing-eval --policies yielding` with S-CGRU's paths (the default) and with CVM's (2 workers each),
    then `crossing-eval compare` of the two: what the learned predictor changes in how `yielding` drives."""
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:  # relative folder names: the report names no machine path
        for out, extra in PREDICTOR_COMPARE_RUNS:
            _crossing_eval(
                ["--policies", "yielding", *extra, "--out", out, "--no-progress", "--workers", "2"], Path(tmp)
            )
        output = _crossing_eval(["compare", *(out for out, _ in PREDICTOR_COMPARE_RUNS)], Path(tmp))
    commands = [
        " ".join(["crossing-eval", "--policies", "yielding", *extra, "--out", out])
        for out, extra in PREDICTOR_COMPARE_RUNS
    ]
    commands.append(" ".join(["crossing-eval", "compare", *(out for out, _ in PREDICTOR_COMPARE_RUNS)]))
    return {"commands": commands, "output": output, "wall_seconds": round(time.perf_counter() - start, 1)}


def _render_predictor_compare(data: dict[str, Any]) -> str:
    commands = ", then ".join(f"`{c}`" for c in data["commands"])
    return (
        f"Measured with {commands} (2 workers, {data['wall_seconds']:.0f} s in all) on commit"
        f" `{data['commit'][:12]}`; rendered from `benchmarks/results/predictor_compare.json` by"
        " `python -m benchmarks.results`.\n\n"
        f"```\n{data['output'].rstrip()}\n```"
    )


def _predictors_fingerprint() -> str:
    from studies.predictor_tables import fingerprint

    return fingerprint()


@dataclass(frozen=True)
class Entry:
    """One registered result: how it is measured, where its JSON lives, where it is rendered."""

    name: str
    """Registry name (the CLI argument)."""
    tier: str
    """'fast' (seconds) or 'slow' (minutes or more): what `--tier` selects."""
    measure: Callable[[], dict[str, Any]]
    """Runs the command and returns the JSON data (without commit and fingerprint, added here)."""
    render: Callable[[dict[str, Any]], str]
    """The markdown block from the JSON data."""
    document: Path
    """The markdown file that holds the block between the markers."""
    behaviour: bool = True
    """Whether the numbers depend on simulated behaviour (then the fingerprint decides staleness)."""
    figures: Callable[[Sequence[Any]], str] | None = None
    """What the entry shows, computed on the fingerprint episodes by the code its numbers come from (None:
    its numbers are not per-episode figures, only what the episodes do counts: speeds, memory, ...)."""
    scenarios: tuple[str, ...] | None = None
    """The built-in scenarios whose fingerprint episodes stand for what it runs (None: every built-in
    scenario, for entries that run them all: a new scenario makes them stale, and only them)."""
    stamps: tuple[Callable[[], str], ...] = ()
    """What else its numbers depend on beyond the fingerprint episodes (the learned policies, a weights
    file)."""
    fingerprint: Callable[[], str] | None = None
    """The entry's own fingerprint, for numbers that do not come from the fingerprint episodes at all (it
    replaces theirs)."""
    data: str = ""
    """Name of the entry whose JSON this block renders, when one measurement feeds two documents."""

    @property
    def json_path(self) -> Path:
        """The committed JSON."""
        return RESULTS_DIR / f"{self.data or self.name}.json"

    def current_fingerprint(self, records: Sequence[Any] | None = None) -> str | None:
        """What the JSON's fingerprint must equal to be current (None: never stale), from `records` (default:
        `fingerprint_records`)."""
        if self.fingerprint is not None:
            return self.fingerprint()
        if not self.behaviour:
            return None
        if records is None:
            return _entry_fingerprint(self)
        if self.scenarios is not None:
            records = [r for r in records if r.task.scenario in self.scenarios]
        digest = hashlib.sha256(dynamics_digest(records).encode())
        if self.figures is not None:
            digest.update(self.figures(records).encode())
        for stamp in self.stamps:
            digest.update(stamp().encode())
        return digest.hexdigest()[:16]


@functools.cache
def _entry_fingerprint(entry: Entry) -> str | None:
    return entry.current_fingerprint(fingerprint_records())


ENTRIES: dict[str, Entry] = {
    e.name: e
    for e in (
        Entry(
            "default_table",
            "slow",
            _measure_default_table,
            _render_default_table,
            REPO / "docs" / "evaluation.md",
            figures=table_figures,
            stamps=DEFAULT_RUN_STAMPS,
        ),
        Entry(
            "default_table_summary",
            "slow",
            _measure_default_table,
            _render_default_headline,
            REPO / "README.md",
            figures=table_figures,
            stamps=DEFAULT_RUN_STAMPS,
            data="default_table",
        ),
        Entry(
            "adversaries",
            "slow",
            _measure_adversaries,
            _render_adversaries,
            REPO / "docs" / "evaluation.md",
            figures=score_figures,
            stamps=(adversary_stamp,),
        ),
        Entry(
            "discrimination",
            "slow",
            _measure_discrimination,
            _render_discrimination,
            REPO / "docs" / "scenario_discrimination.md",
            figures=discrimination_figures,
        ),
        Entry(
            "safe_rl",
            "slow",
            _measure_safe_rl,
            _render_safe_rl,
            REPO / "docs" / "rl.md",
            figures=safe_rl_figures,
            stamps=(learned_stamp,),
        ),
        Entry(
            "safe_rl_summary",
            "slow",
            _measure_safe_rl,
            _render_safe_rl_summary,
            REPO / "README.md",
            figures=safe_rl_figures,
            stamps=(learned_stamp,),
            data="safe_rl",
        ),
        Entry(
            "safe_rl_long",
            "slow",
            _measure_safe_rl_long,
            _render_safe_rl_long,
            REPO / "docs" / "rl.md",
            figures=safe_rl_figures,
        ),
        Entry(
            "intention",
            "slow",
            _measure_intention,
            _render_intention,
            REPO / "predictors" / "INTENTION_RESULTS.md",
            scenarios=WORLD_PROXY,
        ),
        Entry(
            "predictors",
            "slow",
            _measure_predictors,
            _render_predictors,
            REPO / "predictors" / "RESULTS.md",
            fingerprint=_predictors_fingerprint,
        ),
        Entry(
            "predictors_summary",
            "slow",
            _measure_predictors,
            _render_predictors_summary,
            REPO / "docs" / "predictors.md",
            fingerprint=_predictors_fingerprint,
            data="predictors",
        ),
        Entry(
            "predictor_checkpoints",
            "slow",
            _measure_predictor_checkpoints,
            _render_predictor_checkpoints,
            REPO / "predictors" / "RESULTS.md",
            fingerprint=_predictors_fingerprint,
        ),
        Entry(
            "predictor_speed",
            "slow",
            _measure_predictor_speed,
            _render_predictor_speed,
            REPO / "predictors" / "RESULTS.md",
            scenarios=WORLD_PROXY,
        ),
        Entry(
            "value_of_prediction",
            "slow",
            _measure_value_of_prediction,
            _render_value_of_prediction,
            REPO / "docs" / "value_of_prediction.md",
            fingerprint=_value_fingerprint,
        ),
        Entry(
            "value_of_prediction_summary",
            "slow",
            _measure_value_of_prediction,
            _render_value_of_prediction_summary,
            REPO / "README.md",
            fingerprint=_value_fingerprint,
            data="value_of_prediction",
        ),
        Entry(
            "first_result",
            "slow",
            _measure_first_result,
            _render_first_result,
            REPO / "docs" / "benchmarks.md",
            figures=table_figures,
            stamps=DEFAULT_RUN_STAMPS,
        ),
        Entry(
            "first_result_summary",
            "slow",
            _measure_first_result,
            _render_first_result_summary,
            REPO / "README.md",
            figures=table_figures,
            stamps=DEFAULT_RUN_STAMPS,
            data="first_result",
        ),
        Entry(
            "sim_transfer",
            "slow",
            _measure_sim_transfer,
            _render_sim_transfer,
            REPO / "docs" / "predictors.md",
            scenarios=("busy_zebra", "zebra_case1"),
        ),
        _script_entry("env_throughput", "fast", WORLD_PROXY),
        _script_entry("env_throughput_wrappers", "slow", WORLD_PROXY),
        _script_entry("scaling", "slow", WORLD_PROXY),
        _script_entry("eval_throughput", "slow", None, stamps=(learned_stamp,)),
        _script_entry("soak", "slow", WORLD_PROXY),
        _script_entry("world_health", "slow", ("busy_zebra", "four_lane_arterial")),
        _script_entry("oracle_cost", "slow", ("busy_zebra", "zebra_case1")),
        Entry(
            "predictor_compare",
            "slow",
            _measure_predictor_compare,
            _render_predictor_compare,
            REPO / "docs" / "evaluation.md",
            figures=table_figures,
        ),
    )
}


# ---------------------------------------------------------------------------------------------------------
# Rendering and staleness
# ---------------------------------------------------------------------------------------------------------


def _markers(name: str) -> tuple[str, str]:
    return f"<!-- results:{name} -->", f"<!-- /results:{name} -->"


def stale_note(data: dict[str, Any], fingerprint: str | None, name: str = "") -> str:
    """The line rendered above a table whose fingerprint no longer matches the code's."""
    if fingerprint is None or data.get("fingerprint") == fingerprint:
        return ""
    return (
        f"> **Stale:** measured on commit `{str(data.get('commit', 'unknown'))[:12]}` (fingerprint"
        f" `{data.get('fingerprint')}`); what it shows has changed since (`{fingerprint}`)."
        f" Regenerate with `python -m benchmarks.results {name or data.get('name', '')}`.\n\n"
    )


def rendered_block(entry: Entry) -> str:
    """The block between the markers: the stale note (if any) and the entry's rendering of its JSON."""
    data = json.loads(entry.json_path.read_text(encoding="utf-8"))
    note = stale_note(data, entry.current_fingerprint(), entry.data or entry.name)
    return note + entry.render(data)


def is_stale(entry: Entry) -> bool:
    """Whether the entry's JSON is missing or was measured on what no longer matches the code."""
    if not entry.json_path.exists():
        return True
    data = json.loads(entry.json_path.read_text(encoding="utf-8"))
    return bool(stale_note(data, entry.current_fingerprint()))


def last_cost(entry: Entry) -> float | None:
    """Seconds its last measurement took, as its JSON records them (None: not recorded)."""
    if not entry.json_path.exists():
        return None
    data = json.loads(entry.json_path.read_text(encoding="utf-8"))
    cost = data.get("cost_seconds", data.get("wall_seconds"))
    return None if cost is None else float(cost)


def stale_order(entries: Sequence[Entry]) -> list[Entry]:
    """The stale entries, one per JSON, cheapest first by their last cost (unknown costs last, fast tier
    before slow)."""
    chosen: dict[Path, Entry] = {}
    for entry in entries:
        if entry.json_path not in chosen and is_stale(entry):
            chosen[entry.json_path] = entry

    def key(entry: Entry) -> tuple[bool, float, bool, str]:
        cost = last_cost(entry)
        return cost is None, cost or 0.0, entry.tier != "fast", entry.name

    return sorted(chosen.values(), key=key)


def _cost_text(cost: float | None) -> str:
    if cost is None:
        return "last cost unknown"
    return f"last cost {cost / 60:.0f} min" if cost >= 600 else f"last cost {cost:.0f} s"


_BLOCK = r"\n(?:(.*?)\n)?"
"""Between the markers: a newline, then the block and its newline (none yet in a new document)."""


def committed_block(entry: Entry) -> str:
    """What the document holds between the entry's markers now."""
    begin, end = _markers(entry.name)
    text = entry.document.read_text(encoding="utf-8")
    match = re.search(re.escape(begin) + _BLOCK + re.escape(end), text, flags=re.S)
    if match is None:
        raise ValueError(f"{entry.document}: no {begin} ... {end} block")
    return match.group(1) or ""


def write_block(entry: Entry, block: str) -> bool:
    """Replace the entry's block in its document; returns whether the file changed."""
    begin, end = _markers(entry.name)
    text = entry.document.read_text(encoding="utf-8")
    new = re.sub(
        re.escape(begin) + _BLOCK + re.escape(end),
        lambda _: f"{begin}\n{block}\n{end}",
        text,
        count=1,
        flags=re.S,
    )
    if begin not in text or end not in text:
        raise ValueError(f"{entry.document}: no {begin} ... {end} block")
    if new == text:
        return False
    entry.document.write_text(new, encoding="utf-8")
    return True


def measure(entry: Entry) -> float:
    """Run the entry's command and store its JSON with the commit, the fingerprint and the cost (seconds,
    returned)."""
    commit = source_commit()  # before the run: the entry's own JSON and page make the tree dirty after it
    start = time.perf_counter()
    data = entry.measure()
    cost = round(time.perf_counter() - start, 1)
    fingerprint = entry.current_fingerprint() or behaviour_fingerprint()
    data.update(name=entry.data or entry.name, commit=commit, fingerprint=fingerprint, cost_seconds=cost)
    entry.json_path.parent.mkdir(parents=True, exist_ok=True)
    entry.json_path.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    return cost


def _render(entry: Entry) -> None:
    """Write the blocks of every entry that renders `entry`'s JSON."""
    for other in ENTRIES.values():
        if other.json_path == entry.json_path:
            write_block(other, rendered_block(other))


def regenerate_stale() -> list[str]:
    """Measure every stale entry, cheapest first, each JSON written (and its blocks rendered) as soon as it
    finishes: an interrupted run resumes where it stopped, as the finished entries are current. Returns the
    names measured."""
    todo = stale_order(list(ENTRIES.values()))
    if not todo:
        print("every entry is current", file=sys.stderr)
    for k, entry in enumerate(todo, 1):
        cost_text = _cost_text(last_cost(entry))
        print(f"[{k}/{len(todo)}] {entry.name}: measuring ({cost_text}) ...", file=sys.stderr)
        cost = measure(entry)
        _render(entry)
        print(f"[{k}/{len(todo)}] {entry.name}: done in {cost:.0f} s", file=sys.stderr)
    return [e.name for e in todo]


def main(argv: list[str] | None = None) -> int:
    """List, measure, render or check the registered results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help=f"entries to measure: {', '.join(ENTRIES)}")
    parser.add_argument("--tier", choices=("fast", "slow"), help="measure every entry of this tier")
    parser.add_argument("--render", action="store_true", help="re-render every table from its JSON")
    parser.add_argument("--check", action="store_true", help="exit 1 if a rendered table differs")
    parser.add_argument(
        "--stale", action="store_true", help="measure every stale entry, cheapest first (resumable)"
    )
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in ENTRIES]
    if unknown:
        parser.error(f"unknown entries {unknown}; known: {', '.join(ENTRIES)}")
    if args.stale:
        regenerate_stale()
    chosen = list(
        dict.fromkeys([ENTRIES[n] for n in args.names] + [e for e in ENTRIES.values() if e.tier == args.tier])
    )
    measured: set[Path] = set()
    for entry in chosen:
        if entry.json_path in measured:  # two blocks rendered from one JSON: one measurement
            continue
        measured.add(entry.json_path)
        print(f"measuring {entry.name} ...", file=sys.stderr)
        measure(entry)
    differs = []
    for entry in ENTRIES.values():
        if not entry.json_path.exists():
            print(f"{entry.name:28s} not measured: no {entry.json_path.name}")
            differs.append(entry.name)
            continue
        block = rendered_block(entry)
        if args.check:
            if block != committed_block(entry):
                differs.append(entry.name)
        elif chosen or args.render or args.stale:
            write_block(entry, block)
        data = json.loads(entry.json_path.read_text(encoding="utf-8"))
        state = "stale" if is_stale(entry) else "current"
        print(
            f"{entry.name:28s} {state:8s} measured on {str(data.get('commit'))[:12]}"
            f"  {_cost_text(last_cost(entry)):20s}  {entry.document.name}"
        )
    print(f"what the fingerprint episodes do (dynamics digest) in this tree: {behaviour_fingerprint()}")
    if differs:
        print(f"rendered tables differ from their JSON (or have none): {', '.join(differs)}", file=sys.stderr)
        return 1 if args.check else 0
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
