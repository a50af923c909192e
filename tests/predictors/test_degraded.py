"""Degraded oracles: exact at level 0, wrong by the stated amount, seeded, nested, and paired across rows."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import crossing_env  # noqa: F401 - registers the env
from crossing_env.observation import PedestrianColumn
from predictors.degraded import (
    FlippedIntent,
    FlippedIntention,
    NoisyOraclePaths,
    NoisyPaths,
    flip_draws,
    path_errors,
)
from predictors.oracle import OracleIntention, OracleTrajectory
from rollout import WrapperError, wrap
from studies.value_of_prediction import run_rows

HOLD = np.zeros(1, dtype=np.float32)


def _run(env: gym.Env, seed: int, steps: int) -> list[dict[str, np.ndarray]]:
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, *_ = env.step(HOLD)
        out.append(obs)
    return out


def _intent_env(flip: float | None) -> gym.Env:
    env = gym.make("crossing_env/Crossing-v0", scenario="bus_stop_zebra")
    return OracleIntention(env) if flip is None else FlippedIntention(env, flip)


def test_flip_zero_is_the_oracle_and_flip_one_inverts_every_decided_intent() -> None:
    truth = _run(_intent_env(None), 3, 120)
    same = _run(_intent_env(0.0), 3, 120)
    inverted = _run(_intent_env(1.0), 3, 120)
    decided = 0
    for t, s, i in zip(truth, same, inverted, strict=True):
        np.testing.assert_array_equal(s["crossing_intent"], t["crossing_intent"])
        present = t["pedestrians"][:, PedestrianColumn.PRESENCE] > 0.5
        known = present & ((t["crossing_intent"] == 0.0) | (t["crossing_intent"] == 1.0))
        np.testing.assert_array_equal(i["crossing_intent"][known], 1.0 - t["crossing_intent"][known])
        np.testing.assert_array_equal(i["crossing_intent"][~known], t["crossing_intent"][~known])
        decided += int(known.sum())
    assert decided > 100


def test_flips_belong_to_tracks_are_nested_and_match_flip_draws() -> None:
    truth = _run(_intent_env(None), 8, 150)
    low = _run(_intent_env(0.3), 8, 150)
    high = _run(_intent_env(0.6), 8, 150)
    flipped_low: dict[int, bool] = {}
    flipped_high: dict[int, bool] = {}
    for t, lo, hi in zip(truth, low, high, strict=True):
        present = t["pedestrians"][:, PedestrianColumn.PRESENCE] > 0.5
        known = np.flatnonzero(present & ((t["crossing_intent"] == 0.0) | (t["crossing_intent"] == 1.0)))
        for k in known:
            track = int(t["pedestrian_tracks"][k])
            for store, obs in ((flipped_low, lo), (flipped_high, hi)):
                f = bool(obs["crossing_intent"][k] != t["crossing_intent"][k])
                assert store.setdefault(track, f) == f, "a track's flip must not change within an episode"
    assert flipped_low and any(flipped_low.values()) and not all(flipped_high.values())
    assert all(flipped_high[t] for t, f in flipped_low.items() if f), "levels must be nested"
    tracks = np.array(sorted(flipped_low))
    draws = flip_draws(8, tracks)
    np.testing.assert_array_equal(draws < 0.3, [flipped_low[t] for t in tracks])


def _path_env(sigma: float | None) -> gym.Env:
    env = gym.make("crossing_env/Crossing-v0", scenario="busy_zebra")
    if sigma is None:
        return OracleTrajectory(env, plan_accelerations=())
    return NoisyPaths(env, sigma, plan_accelerations=())


def test_noisy_paths_add_exactly_path_errors_and_zero_noise_is_the_oracle() -> None:
    truth = _run(_path_env(None), 5, 40)
    zero = _run(_path_env(0.0), 5, 40)
    noisy = _run(_path_env(1.5), 5, 40)
    checked = 0
    for step, (t, z, n) in enumerate(zip(truth, zero, noisy, strict=True)):
        np.testing.assert_array_equal(z["predicted_paths"], t["predicted_paths"])
        present = np.flatnonzero(t["pedestrians"][:, PedestrianColumn.PRESENCE] > 0.5)
        if not present.size:
            continue
        want = path_errors(5, t["pedestrian_tracks"][present], np.full(present.size, step), 1.5, 12)
        got = n["predicted_paths"][present] - t["predicted_paths"][present]
        np.testing.assert_allclose(got, want, atol=1e-4)
        absent = np.setdiff1d(np.arange(t["pedestrians"].shape[0]), present)
        np.testing.assert_array_equal(n["predicted_paths"][absent], t["predicted_paths"][absent])
        checked += present.size
    assert checked > 50


def test_path_errors_grow_with_the_horizon_at_the_stated_scale() -> None:
    tracks = np.arange(4000) + 1
    err = path_errors(1, tracks, np.zeros_like(tracks), 2.0, 12)
    final = err[:, -1]
    assert abs(final.std() - 2.0) < 0.1  # per axis, at the last step
    np.testing.assert_allclose(err[:, 5], final * 6 / 12)


def test_degraded_names_build_through_the_wrapper_table_and_reject_nonsense() -> None:
    env, used = wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "oracle-flip=0.2", "none")
    flipped = env.forecaster
    assert (
        isinstance(flipped, FlippedIntent) and flipped.flip == 0.2 and used == ["intention:oracle-flip=0.2"]
    )
    env, used = wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "none", "oracle-noise=1")
    assert isinstance(env.forecaster, NoisyOraclePaths) and env.forecaster.sigma == 1.0
    with pytest.raises(WrapperError, match="needs a number"):
        wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "oracle-flip=lots", "none")
    with pytest.raises(WrapperError, match="probability"):
        wrap(gym.make("crossing_env/Crossing-v0", scenario="zebra_case1"), "oracle-flip=1.5", "none")


def test_the_accuracy_sweep_is_paired_on_seeds_and_resumes(tmp_path: Path) -> None:
    """Every row of the study meets the same situations; a second call reads the stored rows, runs nothing."""
    rows = [("none", "none"), ("oracle-flip=0.3", "none")]
    episodes = dict.fromkeys(rows, 2)
    first = run_rows(rows, ["ncap_cpna"], episodes, tmp_path, workers=1)
    keys = [[(r["scenario"], r["episode"], r["seed"]) for r in first[row]] for row in rows]
    assert keys[0] == keys[1] and len(keys[0]) == 2
    stamps = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    again = run_rows(rows, ["ncap_cpna"], episodes, tmp_path, workers=1)
    assert again == first
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()} == stamps


def test_a_row_whose_fingerprint_changed_is_re_run_alone(tmp_path: Path) -> None:
    """Rows are stamped one by one: a change to one predictor re-runs its row and keeps the others."""
    rows = [("none", "none"), ("oracle-flip=0.3", "none")]
    episodes = dict.fromkeys(rows, 1)
    run_rows(rows, ["ncap_cpna"], episodes, tmp_path, workers=1, fingerprint=lambda i, p: "old")
    stamps = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    changed = "oracle-flip_0.3__none.json"

    def fingerprint(intention: str, predictor: str) -> str:
        return "new" if intention.startswith("oracle-flip") else "old"

    run_rows(rows, ["ncap_cpna"], episodes, tmp_path, workers=1, fingerprint=fingerprint)
    after = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    assert after["none__none.json"] == stamps["none__none.json"]
    assert after[changed] != stamps[changed]
    assert json.loads((tmp_path / changed).read_text())["fingerprint"] == "new"


def test_an_intent_row_goes_stale_when_its_weights_file_changes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A new release bound may not move a short probe rollout, so the weights file is part of the stamp of
    every row whose wrapper reads it, and of no other row."""
    import predictors.learned_intent_weights as liw
    from studies.value_of_prediction import _probe_digest

    probe = _probe_digest.__wrapped__
    before = probe("learned", "none"), probe("oracle-flip=0.4", "none")
    edited = tmp_path / "learned_intent.json"
    edited.write_bytes(liw.WEIGHTS_PATH.read_bytes() + b"\n")
    monkeypatch.setattr(liw, "WEIGHTS_PATH", edited)
    after = probe("learned", "none"), probe("oracle-flip=0.4", "none")
    assert after[0] != before[0]
    assert after[1] == before[1]


def test_a_path_row_goes_stale_when_plan_scoring_changes_outside_the_zebra(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The deferred-conflict charge moved no zebra probe of the small path-noise rows; the NCAP probe
    catches it (measured: the 0.25 m row's zebra rollout is the same with and without the charge)."""
    import agents.plans as plans
    from studies.value_of_prediction import _probe_digest, probe_scenarios

    assert probe_scenarios("none") == ("zebra_case1",)
    assert "ncap_cpna" in probe_scenarios("oracle-noise=0.25")
    probe = _probe_digest.__wrapped__
    before = probe("none", "oracle-noise=0.25")
    monkeypatch.setattr(plans, "_deferred_cost", lambda conflict, *_: np.zeros_like(conflict))
    monkeypatch.setattr(plans, "_deferred_wait", lambda y, gap, *_: np.zeros(gap.shape[:2]))
    assert probe("none", "oracle-noise=0.25") != before


def test_a_plan_row_goes_stale_when_the_plan_scoring_code_changes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The wait charge of `agents.plans` left every short probe of the path-oracle rows as it was, so the
    scoring source is part of those rows' stamps, and of no other row's."""
    import studies.value_of_prediction as vop

    assert vop.scores_plans("oracle") and vop.scores_plans("oracle-noise=1.5")
    assert not vop.scores_plans("cvm") and not vop.scores_plans("none")
    probe = vop._probe_digest.__wrapped__
    before = probe("none", "oracle-noise=1.5"), probe("none", "cvm")
    source = vop.PLAN_SCORING_FILES[0].read_text()
    edited = tmp_path / "plans.py"
    edited.write_text(source.replace("SUBSTEPS = 4", "SUBSTEPS = 4  # per interval\nUNUSED = 1"))
    monkeypatch.setattr(vop, "PLAN_SCORING_FILES", (edited,))
    after = probe("none", "oracle-noise=1.5"), probe("none", "cvm")
    assert after[0] != before[0]
    assert after[1] == before[1]


def test_the_plan_scoring_stamp_ignores_docstrings_comments_and_layout() -> None:
    """A docstring edit once sent the committed value table stale: only code edits move the stamp."""
    import studies.value_of_prediction as vop

    source = vop.PLAN_SCORING_FILES[0].read_text(encoding="utf-8")
    stamp = vop.code_without_docs(source)
    assert '"""' not in stamp and "Ego integration steps" not in stamp
    reworded = source.replace("Ego integration steps", "Integration steps of the ego").replace(
        "\n        collision |= (", "\n        # a forecast overlap\n        collision |= ("
    )
    assert reworded != source and "# a forecast overlap" in reworded
    assert vop.code_without_docs(reworded + "\n\n") == stamp
    assert vop.code_without_docs(source.replace("WALKING_ACROSS = 0.2", "WALKING_ACROSS = 0.3")) != stamp
    assert vop.code_without_docs('def f():\n    """Only a docstring."""\n') == "def f():\n    pass"
