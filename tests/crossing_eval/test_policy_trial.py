"""Issue 44: a plug-in policy that raises, exits or answers with no action is one line and exit 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import crossing_eval.cli as cli
from rollout import ActionError, checked_action

PLUGIN = "tests.crossing_eval.plugin_policies"
TINY = ["--scenarios", "zebra_case1", "--episodes", "2", "--no-progress"]


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("crossing-eval: error:")]
    assert len(errors) == 1 and "Traceback" not in "\n".join(err), err
    return errors[0]


@pytest.mark.parametrize(
    ("policy", "said"),
    [
        (f"{PLUGIN}:RaisesInReset", "reset(seed=2024) failed: KeyError: 'episode_state'"),
        (f"{PLUGIN}:ResetWithoutSeed", "reset(seed=2024) failed: TypeError"),
        (f"{PLUGIN}:ReturnsNaN", "its first action failed: ActionError: the action must be finite"),
        (f"{PLUGIN}:ReturnsText", "its first action failed: ActionError: the action must be a real number"),
        (f"{PLUGIN}:ExitsInInit", "building it called sys.exit('no GPU')"),
        ("tests.crossing_eval.plugin_raises_on_import:Any", "this plug-in needs a licence key"),
    ],
)
def test_a_plug_in_that_fails_its_trial_stops_the_run_before_any_episode(
    policy: str,
    said: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))
    out = tmp_path / "out"
    try:
        code = cli.main([*TINY, "--workers", "1", "--policies", policy, "--out", str(out)])
    except SystemExit as exc:  # an argument error (the module cannot be imported): argparse's exit 2
        code = exc.code
    assert code == 2
    line = _one_line(capsys)
    assert policy in line and said in line, line
    assert not out.exists()


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_sys_exit_in_an_episode_is_an_error_naming_the_policy_not_a_silent_exit(
    workers: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    policy = f"{PLUGIN}:ExitsLater"
    assert cli.main([*TINY, "--workers", workers, "--policies", policy, "--out", str(out)]) == 2
    line = _one_line(capsys)
    assert policy in line and "sys.exit(3)" in line, line
    assert not out.exists()


@pytest.mark.parametrize(
    "raw", ["0.5", b"0.5", True, np.array([True]), None, [0.1, 0.2], np.zeros(3), np.nan, [np.inf], object()]
)
def test_what_is_not_an_action_is_refused(raw: object) -> None:
    with pytest.raises(ActionError):
        checked_action(raw)


@pytest.mark.parametrize("raw", [0.5, 1, np.float64(-0.3), np.array([0.2]), np.array(0.2, np.float32), [0.1]])
def test_real_numbers_are_actions(raw: object) -> None:
    action = checked_action(raw)
    assert action.dtype == np.float32 and action.shape == (1,)
    assert action[0] == np.float32(np.asarray(raw, dtype=np.float64).reshape(-1)[0])
