"""`crossing-eval` end to end (tiny budgets), determinism across worker counts, bad input, and Ray."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from crossing_eval.outputs import worst_records
from crossing_eval.runners import run_tasks
from crossing_eval.tasks import EpisodeTask, episode_seed, make_tasks

REPO = Path(__file__).resolve().parents[2]
SMALL = [
    "--scenarios",
    "occluded_parked_car,midblock_jaywalker",
    "--policies",
    "yielding,constant_speed",
    "--episodes",
    "2",
    "--predictor",
    "cvm",
    "--no-progress",
]


def run_cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    return subprocess.run(
        [sys.executable, "-m", "crossing_eval.cli", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


@pytest.fixture(scope="module")
def one_worker(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str], Path]:
    out = tmp_path_factory.mktemp("eval1")
    return run_cli(*SMALL, "--workers", "1", "--out", str(out)), out


def test_cli_writes_table_json_csv_png_and_logs(
    one_worker: tuple[subprocess.CompletedProcess[str], Path],
) -> None:
    proc, out = one_worker
    assert proc.returncode == 0, proc.stderr
    assert "score [95% CI]" in proc.stdout and "ped. at fault" in proc.stdout  # the headline table
    assert "collision rate [95% CI]" in (out / "table_full.txt").read_text()
    for name in ("yielding", "constant_speed"):
        assert name in proc.stdout
    assert "overall" not in proc.stdout  # no row pools different policies

    doc = json.loads((out / "results.json").read_text())
    assert doc["settings"]["episodes"] == 2
    assert len(doc["episodes"]) == 2 * 2 * 2
    keys = [(e["scenario"], e["policy"], e["episode"]) for e in doc["episodes"]]
    assert keys == sorted(keys)
    assert set(doc["summary"]["per_policy"]) == {"yielding", "constant_speed"}
    # Paired seeds: both policies meet the same situations.
    seeds = {(e["scenario"], e["episode"]): set() for e in doc["episodes"]}
    for e in doc["episodes"]:
        seeds[(e["scenario"], e["episode"])].add(e["seed"])
    assert all(len(s) == 1 for s in seeds.values())
    # The occluded pedestrian is hit by the constant-speed car in every seed of this scenario.
    cs = [
        e
        for e in doc["episodes"]
        if e["policy"] == "constant_speed" and e["scenario"] == "occluded_parked_car"
    ]
    assert all(e["metrics"]["collision"] for e in cs)
    assert doc["summary"]["per_policy"]["constant_speed"]["collision_rate"] > 0.0

    with (out / "episodes.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 8
    assert {r["policy"] for r in rows} == {"yielding", "constant_speed"}
    with (out / "summary.csv").open() as fh:
        summary_rows = list(csv.DictReader(fh))
    assert [r["policy"] for r in summary_rows] == ["yielding", "constant_speed"]
    assert "overall" not in doc["summary"]
    report = (out / "report.md").read_text()
    assert "## Definitions" in report and "overall" not in report

    for png in ("safety_vs_efficiency.png", "min_ttc.png"):
        data = (out / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000

    worst = sorted((out / "worst").glob("*.json"))
    assert worst, "no worst-episode logs written"
    log = json.loads(worst[0].read_text())
    assert log["policy"] == "constant_speed"  # a collision ranks first
    assert {json.loads(p.read_text())["policy"] for p in worst} == {"constant_speed", "yielding"}
    assert len(log["actions"]) > 10
    assert not list(out.glob(".*.tmp")), "temporary files left behind"


def test_worker_count_does_not_change_results(
    one_worker: tuple[subprocess.CompletedProcess[str], Path], tmp_path: Path
) -> None:
    proc1, out1 = one_worker
    assert proc1.returncode == 0, proc1.stderr
    proc2 = run_cli(*SMALL, "--workers", "2", "--out", str(tmp_path))
    assert proc2.returncode == 0, proc2.stderr
    assert (out1 / "results.json").read_bytes() == (tmp_path / "results.json").read_bytes()
    assert (out1 / "episodes.csv").read_bytes() == (tmp_path / "episodes.csv").read_bytes()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--episodes", "0"], "'0'"),
        (["--episodes", "many"], "'many'"),
        (["--policies", "yielding,teleport"], "'teleport'"),
        (["--scenarios", "atlantis"], "'atlantis'"),
        (["--workers", "-3"], "'-3'"),
        (["--backend", "slurm"], "'slurm'"),
        (["--address", "auto"], "'auto'"),
    ],
)
def test_bad_arguments_exit_2_naming_the_value(args: list[str], needle: str, tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = run_cli(*args, "--out", str(out), timeout=60)
    assert proc.returncode == 2
    assert needle in proc.stderr
    assert not out.exists(), "nothing may be written on bad input"


def test_seeds_are_deterministic_and_policy_independent() -> None:
    assert episode_seed(7, "zebra_case1", 3) == episode_seed(7, "zebra_case1", 3)
    assert episode_seed(7, "zebra_case1", 3) != episode_seed(7, "zebra_case1", 4)
    assert episode_seed(7, "zebra_case1", 3) != episode_seed(8, "zebra_case1", 3)
    assert episode_seed(7, "zebra_case1", 3) != episode_seed(7, "busy_zebra", 3)
    tasks = make_tasks(["zebra_case1"], ["yielding", "ttc_brake"], 2, 7, predictor="cvm", intention="none")
    assert [t.seed for t in tasks if t.policy == "yielding"] == [
        t.seed for t in tasks if t.policy == "ttc_brake"
    ]
    assert {t.predictor for t in tasks if t.policy == "ttc_brake"} == {"none"}
    assert {t.predictor for t in tasks if t.policy == "yielding"} == {"cvm"}


def test_run_tasks_in_process_matches_and_ranks_worst() -> None:
    tasks = [
        EpisodeTask("occluded_parked_car", "constant_speed", 0, 11),
        EpisodeTask("zebra_case1", "yielding", 0, 11),
    ]
    a = run_tasks(tasks, workers=1, show_progress=False)
    b = run_tasks(list(reversed(tasks)), workers=1, show_progress=False)
    assert [r.result for r in a] == [r.result for r in b]
    assert [r.actions for r in a] == [r.actions for r in b]
    worst = worst_records(a, 1)
    assert worst[0].task.policy == "constant_speed" and worst[0].result["collision"]


# --------------------------------------------------------------------------------------------- Ray


@pytest.fixture(scope="module")
def ray_local():
    ray = pytest.importorskip("ray", reason="optional extra 'ray' not installed")
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        object_store_memory=100 * 2**20,
        log_to_driver=False,
    )
    yield ray
    ray.shutdown()


@pytest.mark.ray
def test_ray_backend_matches_local(ray_local) -> None:
    tasks = make_tasks(["zebra_case1"], ["yielding", "ttc_brake"], 2, 5, predictor="cvm", intention="none")
    local = run_tasks(tasks, workers=1, show_progress=False)
    remote = run_tasks(tasks, backend="ray", show_progress=False)
    assert [r.key for r in remote] == [r.key for r in local]
    assert [r.result for r in remote] == [r.result for r in local]
    assert [r.actions for r in remote] == [r.actions for r in local]
