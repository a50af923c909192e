"""Small runs stay in this process, reusing the preflight's envs and models; the records do not change."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

import pytest

import crossing_eval.cli as cli
import crossing_eval.runners as runners
from crossing_eval import tasks as tasks_module
from crossing_eval.runners import pool_pays_off, run_tasks
from crossing_eval.tasks import make_tasks

REPO = Path(__file__).resolve().parents[2]
SMALL = ["--scenarios", "zebra_case1", "--policies", "yielding,constant_speed", "--episodes", "2"]


def test_the_pool_pays_off_only_for_enough_episodes() -> None:
    assert not pool_pays_off(1000, 1)
    assert not pool_pays_off(7, 2)  # the smoke run with forkserver workers: in this process
    assert pool_pays_off(7, 2, "fork")  # forked workers start with this process's envs and models
    assert not pool_pays_off(1, 2, "fork")
    assert pool_pays_off(315, 2)  # the default table: a pool
    assert pool_pays_off(None, 2)  # an unknown number of episodes: a pool
    assert not pool_pays_off(5, 16) and pool_pays_off(40, 16)


def test_workers_fork_while_torch_is_not_imported(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, "torch", raising=False)
    assert runners.pool_start_method() == "fork"
    monkeypatch.setitem(sys.modules, "torch", types.ModuleType("torch"))
    assert runners.pool_start_method() == "forkserver"


def test_the_default_run_imports_no_torch(tmp_path: Path) -> None:
    """The shipped S-CGRU (kernel file) and learned policy (npz) run without torch: 1.5 s per process."""
    code = (
        "import sys; import crossing_eval.cli as c;"
        f" assert c.main(['--scenarios', 'zebra_case1', '--episodes', '1', '--workers', '1', '--no-progress',"
        f" '--out', {str(tmp_path / 'out')!r}]) == 0;"
        " assert 'torch' not in sys.modules, 'torch imported';"
        " assert 'pandas' not in sys.modules, 'pandas imported (highway-env env registry)'"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_forked_workers_give_the_in_process_records(monkeypatch: pytest.MonkeyPatch) -> None:
    tasks = make_tasks(["zebra_case1"], ["yielding", "constant_speed"], 2, 2024)
    monkeypatch.setattr(tasks_module, "_ENV_CACHE", {})
    monkeypatch.delitem(sys.modules, "torch", raising=False)  # fork is chosen only without torch
    monkeypatch.setattr(runners, "pool_start_method", lambda: "fork")
    here = run_tasks(tasks, workers=1, show_progress=False)
    forked = run_tasks(tasks, workers=2, show_progress=False)
    assert [(r.key, r.result, r.actions, r.episode_return) for r in here] == [
        (r.key, r.result, r.actions, r.episode_return) for r in forked
    ]


def test_a_small_run_starts_no_pool_and_reuses_the_preflight_envs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tasks_module, "_ENV_CACHE", {})

    def no_pool(*args: object, **kwargs: object) -> None:
        raise AssertionError("a small run started a worker pool")

    monkeypatch.setattr(runners, "ProcessPoolExecutor", no_pool)
    monkeypatch.setattr(cli, "pool_start_method", lambda: "forkserver")  # as when torch is imported
    built: list[tuple[object, ...]] = []
    make_env = tasks_module.make_env
    monkeypatch.setattr(tasks_module, "make_env", lambda *a, **k: built.append((a, k)) or make_env(*a, **k))
    argv = [*SMALL, "--workers", "2", "--no-progress", "--out", str(tmp_path / "out")]
    assert cli.main(argv) == 0
    assert "in this process" in capsys.readouterr().err
    assert len(built) == 2  # (qlb, s-cgru) for yielding and none for constant_speed, built once each


def test_in_process_records_equal_the_pool_records(monkeypatch: pytest.MonkeyPatch) -> None:
    tasks = make_tasks(["zebra_case1"], ["yielding", "constant_speed"], 2, 2024)
    monkeypatch.setattr(tasks_module, "_ENV_CACHE", {})
    tasks_module.cached_env("zebra_case1", "qlb", "s-cgru")  # as the preflight leaves it
    here = run_tasks(tasks, workers=1, show_progress=False)
    pool = run_tasks(tasks, workers=2, show_progress=False)
    assert [r.key for r in here] == [r.key for r in pool]
    assert [r.result for r in here] == [r.result for r in pool]
    assert [r.actions for r in here] == [r.actions for r in pool]
    assert [r.episode_return for r in here] == [r.episode_return for r in pool]


def test_a_warm_up_leaves_no_trace_in_the_next_episode(monkeypatch: pytest.MonkeyPatch) -> None:
    """The warm-up before forking runs the first steps of an episode on the env the workers then reuse."""
    monkeypatch.setattr(tasks_module, "_ENV_CACHE", {})
    first, second = make_tasks(["zebra_case1"], ["yielding"], 2, 2024)
    fresh = tasks_module.run_episode(second)
    tasks_module.warm_up(first)
    after = tasks_module.run_episode(second)
    assert (after.result, after.actions, after.episode_return) == (
        fresh.result,
        fresh.actions,
        fresh.episode_return,
    )


def test_the_slowest_tasks_go_first_and_the_rest_keep_their_order() -> None:
    tasks = make_tasks(["zebra_case1"], ["constant_speed", "predictive_yielding", "ttc_brake"], 2, 7)
    ordered = tasks_module.heaviest_first(tasks)
    assert [t.policy for t in ordered] == ["predictive_yielding"] * 2 + ["constant_speed"] * 2 + [
        "ttc_brake"
    ] * 2
    assert sorted(ordered, key=lambda t: (t.policy, t.episode)) == tasks


def test_the_command_passes_main_s_exit_status_on() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "crossing_eval.cli", "--scenarios", "no_such_scenario"],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert proc.returncode == 2 and "unknown scenario 'no_such_scenario'" in proc.stderr
