"""CLI help (issue 16): defaults and choices shown, no reStructuredText markup, no empty defaults."""

from __future__ import annotations

import pytest

from crossing_eval.cli import build_parser as eval_parser
from crossing_replay.cli import build_parser as replay_parser


def _help(parser, argv: list[str], capsys) -> str:
    with pytest.raises(SystemExit):
        parser.parse_args([*argv, "--help"])
    return capsys.readouterr().out


@pytest.mark.parametrize(
    ("name", "argv", "needles"),
    [
        ("eval", [], ["(default: 5)", "(default: 2024)", "(default: s-cgru)", "yielding"]),
        ("replay", ["record"], ["(default: constant)", "{classical,learned,oracle,qlb,none}"]),
        ("replay", ["scene"], ["which recording set", "(default: s-cgru)", "--fallback-cvm"]),
        ("replay", ["screenshot"], ["(default: 9877)", "(default: 500)"]),
        ("replay", ["video"], ["(default: 10)", ".mp4", ".gif"]),
        ("replay", ["episode"], ["--without-predictors"]),
    ],
)
def test_help_shows_defaults_and_no_markup(name, argv, needles, capsys):
    parser = eval_parser() if name == "eval" else replay_parser()
    text = _help(parser, argv, capsys)
    for needle in needles:
        assert needle in " ".join(text.split()), needle
    assert "``" not in text and "(default: )" not in text and "(default: None)" not in text


def test_train_help_lists_models_and_scenes(capsys):
    from predictors.train import parse_args

    with pytest.raises(SystemExit):
        parse_args(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "{s-cgru,s-gru,s-lstm,lstm}" in text and "zara2" in text and "(default: 20)" in text
    assert "``" not in text and "(default: )" not in text


def test_ppo_example_help_shows_defaults(capsys, monkeypatch):
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "ppo_crossing.py"
    spec = importlib.util.spec_from_file_location("ppo_crossing_help", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)  # dataclasses look their module up
    spec.loader.exec_module(module)
    with pytest.raises(SystemExit):
        module.parse_args(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: 200000)" in text and "(default: 4)" in text and "(default: runs/ppo)" in text


def test_list_names_every_choice_with_a_line_and_imports_no_plugin(monkeypatch, capsys):
    """``crossing-eval --list``: scenarios, policies, predictors and intention models, one line each."""
    import agents.registry as registry
    import rollout.wrappers as wrappers
    from agents.registry import policy_names
    from crossing_eval.cli import main
    from scenarios import list_scenarios

    monkeypatch.setattr(registry, "installed_policies", lambda: {"their_car": "not_installed_xyz:Car"})
    monkeypatch.setattr(wrappers, "installed_predictors", lambda: {"their_model": "not_installed_xyz:M"})
    with pytest.raises(SystemExit) as exc:
        main(["--policies", "no_such_policy", "--list"])  # --list wins, like --help
    assert exc.value.code == 0
    out = capsys.readouterr().out
    flat = " ".join(out.split())
    for name, description in list_scenarios().items():
        assert f" {name} {' '.join(description.rstrip('.').split())}" in flat
    for name in (*policy_names(), "s-cgru", "cvm", "oracle-noise=SIGMA", "qlb", "classical", "learned"):
        assert f" {name} " in flat, name
    assert "not_installed_xyz:Car" in out and "not_installed_xyz:M" in out  # listed, never imported
    assert "`" not in out
    assert max(len(line) for line in out.splitlines()) <= 100


def test_help_names_the_built_in_scenarios(capsys):
    from scenarios import available_scenarios

    text = " ".join(_help(eval_parser(), [], capsys).split())
    for name in available_scenarios():
        assert name in text, name
