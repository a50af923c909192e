"""Issue 25: whatever cannot be loaded stops the run before the first episode (one line, exit 2)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import agents.registry as registry
import crossing_eval.cli as cli
from crossing_eval.outputs import file_slug

PLUGIN = "tests.crossing_eval.plugin_policies"
TINY = ["--scenarios", "zebra_case1", "--episodes", "1", "--workers", "1", "--no-progress"]


def _no_episodes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli, "run_tasks", lambda *a, **k: pytest.fail("episodes ran"))


def _one_error_line(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("crossing-eval: error:")]
    assert len(errors) == 1, err
    assert "Traceback" not in "\n".join(err)
    for needle in needles:
        assert needle in errors[0], errors[0]
    return errors[0]


def test_predictor_that_cannot_load_fails_before_any_episode(tmp_path: Path, capsys, monkeypatch) -> None:
    bad = tmp_path / "model.pt"
    bad.write_text("not a checkpoint")
    _no_episodes(monkeypatch)
    argv = [*TINY, "--policies", "predictive_yielding", "--predictor", str(bad), "--out", str(tmp_path / "o")]
    code = cli.main(argv)
    assert code == 2
    _one_error_line(capsys, "model.pt")
    assert not (tmp_path / "o").exists(), "nothing written"


def test_plugin_that_cannot_be_built_fails_in_the_parent(tmp_path: Path, capsys, monkeypatch) -> None:
    _no_episodes(monkeypatch)
    code = cli.main([*TINY, "--policies", f"{PLUGIN}:NeedsThings", "--out", str(tmp_path / "o")])
    assert code == 2
    _one_error_line(capsys, "NeedsThings", "cannot be built")


def test_plugin_with_a_no_argument_constructor_runs(tmp_path: Path) -> None:
    assert cli.main([*TINY, "--policies", f"{PLUGIN}:Fixed", "--out", str(tmp_path / "o")]) == 0


def test_tampered_shipped_policy_is_refused(tmp_path: Path, monkeypatch) -> None:
    weights = tmp_path / "weights"
    shutil.copytree(registry.WEIGHTS_DIR, weights)
    monkeypatch.setattr(registry, "WEIGHTS_DIR", weights)
    monkeypatch.setattr(registry, "SHIPPED_MANIFEST", weights / "manifest.json")
    monkeypatch.setattr(registry, "_VERIFIED", set())
    registry.verify_shipped_policy_files()  # the copy is intact
    monkeypatch.setattr(registry, "_VERIFIED", set())
    data = bytearray((weights / "ppo_shielded.npz").read_bytes())
    data[-1] ^= 1
    (weights / "ppo_shielded.npz").write_bytes(bytes(data))
    with pytest.raises(registry.ShippedPolicyError, match=r"ppo_shielded\.npz.*manifest"):
        registry.verify_shipped_policy_files()


def test_episodes_have_a_documented_bound(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["--episodes", str(cli.MAX_EPISODES + 1)])
    assert exc.value.code == 2 and "at most" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("spec", "slug"),
    [
        ("yielding", "yielding"),
        ("sb3:/runs/a/model.zip", "sb3-model"),
        (f"{PLUGIN}:Coast", "tests.crossing_eval.plugin_policies-Coast"),
        ("../../etc", "etc"),
    ],
)
def test_worst_episode_names_are_flat(spec: str, slug: str) -> None:
    assert file_slug(spec) == slug and "/" not in file_slug(spec)


def test_results_record_their_provenance(tmp_path: Path) -> None:
    import json

    out = tmp_path / "o"
    assert cli.main([*TINY, "--policies", "predictive_yielding", "--out", str(out)]) == 0
    prov = json.loads((out / "results.json").read_text())["settings"]["provenance"]
    assert prov["scenario_durations"] == {"zebra_case1": 35.0}
    assert "predictors/weights/s-cgru_all.pt" in prov["files"] and len(prov["files"]) == 1
    assert prov["command"].startswith("crossing-eval --scenarios zebra_case1")
    assert prov["package_version"] and prov["commit"]
