"""Plug-ins in `crossing-eval`: pkg.module:attr, entry points, SB3 zips, predictor checkpoints."""

from __future__ import annotations

import os
import sys
from importlib.metadata import EntryPoint
from pathlib import Path

import numpy as np
import pytest

import agents.registry as registry
from agents import Policy, make_policy, policy_names, register_policy
from agents.policy import FunctionPolicy
from crossing_eval.cli import build_parser, main
from crossing_eval.runners import run_tasks
from crossing_eval.tasks import make_tasks

PLUGIN = "tests.crossing_eval.plugin_policies"
ARGS = ["--scenarios", "zebra_case1", "--episodes", "2", "--no-progress"]


def test_module_attr_factory_and_class_protocol():
    from tests.crossing_eval.plugin_policies import Coast

    obs = {"ego": np.zeros(6, np.float32)}
    assert make_policy(f"{PLUGIN}:gentle_brake")(obs)[0] == pytest.approx(-0.2)
    coast = make_policy(f"{PLUGIN}:Coast", throttle=0.3)  # no reset(): adapted as a stateless policy
    assert isinstance(coast, FunctionPolicy) and isinstance(coast.function, Coast)
    assert coast(obs)[0] == pytest.approx(0.3)
    fixed = make_policy(f"{PLUGIN}:Fixed")  # a no-argument constructor, a full Policy: used as it is
    assert isinstance(fixed, Policy) and fixed(obs)[0] == pytest.approx(0.05)
    with pytest.raises(ValueError, match="has no attribute 'nope'"):
        make_policy(f"{PLUGIN}:nope")
    with pytest.raises(ValueError, match="cannot import module"):
        make_policy("no_such_module_xyz:policy")


def test_a_plain_function_is_the_policy_and_a_factory_is_called():
    from tests.crossing_eval import plugin_policies as mod

    obs = {"ego": np.zeros(6, np.float32)}
    cruise = make_policy(f"{PLUGIN}:cruise")  # def cruise(obs): the policy itself, never called to build
    assert isinstance(cruise, FunctionPolicy) and cruise.function is mod.cruise
    assert cruise(obs)[0] == pytest.approx(0.25)
    assert make_policy(f"{PLUGIN}:cruise_at")(obs)[0] == pytest.approx(0.5)  # def cruise_at(obs, gain=2)
    assert not registry._takes_observation(mod.gentle_brake)  # (scenario=None, dt=None): a factory
    assert not registry._takes_observation(lambda scenario: None)  # requires only a factory keyword
    assert not registry._takes_observation(lambda **kw: None)
    assert registry._takes_observation(lambda o, /: None)


def test_a_plain_function_in_the_current_folder(tmp_path: Path, monkeypatch, capsys):
    """The README's newcomer: ``mypol.py`` with ``def cruise(obs)`` beside them, no PYTHONPATH."""
    name = f"newcomer_{tmp_path.name.replace('-', '_')}"
    (tmp_path / f"{name}.py").write_text(
        "import numpy as np\n\ndef cruise(obs):\n    return np.array([0.2], dtype=np.float32)\n"
    )
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(tmp_path))])
    code = main([*ARGS[:2], "--episodes", "1", "--no-progress", "--policies", f"{name}:cruise,yielding"])
    assert code == 0
    assert f"{name}:cruise" in capsys.readouterr().out
    assert (tmp_path / "crossing-eval-results" / "latest" / "results.json").is_file()


def test_register_policy_and_entry_points(monkeypatch):
    register_policy("gentle_test", registry._import_attr(f"{PLUGIN}:gentle_brake"))
    try:
        assert "gentle_test" in policy_names()
        with pytest.raises(ValueError, match="already registered"):
            register_policy("gentle_test", lambda **_: None)
        assert make_policy("gentle_test")({"ego": np.zeros(6)})[0] == pytest.approx(-0.2)
    finally:
        registry._REGISTRY.pop("gentle_test")
    ep = EntryPoint("coaster", f"{PLUGIN}:Coast", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry, "entry_points", lambda group: [ep] if group == ep.group else [])
    assert "coaster" in policy_names()
    assert make_policy("coaster")({"ego": np.zeros(6)})[0] == pytest.approx(0.1)
    assert "coaster" in build_parser().format_help()  # --help lists installed plug-ins


def test_help_lists_the_names():
    text = " ".join(build_parser().format_help().split())
    for name in (
        "yielding",
        "constant_speed",
        "always_cautious",
        "ppo_shielded",
        "pkg.module:attr",
        "sb3:",
        "mlp:",
    ):
        assert name in text


@pytest.mark.slow
def test_plugin_and_sb3_rows_with_two_workers(sb3_zip: Path, tmp_path: Path, capsys):
    spec = f"{PLUGIN}:gentle_brake"
    code = main([*ARGS, "--policies", f"{spec},sb3:{sb3_zip}", "--workers", "2", "--out", str(tmp_path)])
    assert code == 0
    table = capsys.readouterr().out
    assert spec in table
    assert f"sb3:{sb3_zip.resolve()}" in table


def test_sb3_policy_uses_its_vecnormalize_statistics(sb3_zip: Path):
    from agents.sb3 import SB3Policy

    pol = SB3Policy(sb3_zip)
    assert pol.stats is not None and not pol.uses_predictors
    obs = {k: np.ones(s.shape, np.float32) for k, s in pol.model.observation_space.spaces.items()}
    norm = pol.normalise({k: v[None] for k, v in obs.items()})
    rms = pol.stats["obs_rms"]["ego"]
    expected = np.clip((1.0 - rms.mean) / np.sqrt(rms.var + pol.stats["epsilon"]), -10, 10)
    np.testing.assert_allclose(norm["ego"][0], expected, rtol=1e-5)
    action = pol(obs)
    assert action.shape == (1,) and action.dtype == np.float32 and -1 <= action[0] <= 1


def test_bad_plugins_and_predictors_exit_2(tmp_path: Path, capsys):
    for bad, needle in (
        (["--policies", "sb3:/no/such/model.zip"], "no such file"),
        (["--policies", "no_such_module_xyz:policy"], "cannot import module"),
        (["--predictor", str(tmp_path / "missing.pt")], "missing.pt"),
    ):
        with pytest.raises(SystemExit) as exc:
            main([*ARGS, *bad, "--out", str(tmp_path)])
        assert exc.value.code == 2
        assert needle in capsys.readouterr().err


def test_predictor_takes_a_checkpoint_path():
    from predictors.checkpoints import WEIGHTS_DIR

    ckpt = WEIGHTS_DIR / "s-cgru_all.pt"
    rel = os.path.relpath(ckpt)
    args = build_parser().parse_args(["--predictor", rel])
    assert args.predictor == str(ckpt.resolve())
    tasks = make_tasks(["zebra_case1"], ["yielding"], 1, 3, predictor=args.predictor, intention="none")
    (record,) = run_tasks(tasks, workers=1, show_progress=False)
    assert record.predictors == [f"trajectory:{ckpt.resolve()}"]


@pytest.mark.ray
@pytest.mark.slow
def test_plugin_and_sb3_policies_as_ray_tasks(sb3_zip: Path):
    ray = pytest.importorskip("ray", reason="optional extra 'ray' not installed")
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    tasks = make_tasks(
        ["zebra_case1"], [f"{PLUGIN}:gentle_brake", f"sb3:{sb3_zip.resolve()}"], 1, 5, "none", "none"
    )
    local = run_tasks(tasks, workers=1, show_progress=False)
    remote = run_tasks(tasks, workers=2, backend="ray", show_progress=False)
    assert not ray.is_initialized()
    assert [r.actions for r in remote] == [r.actions for r in local]
