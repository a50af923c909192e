"""Tests of `crossing-replay`: recordings are read back with rerun's RrdReader and checked."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from crossing_replay.cli import main  # noqa: E402
from crossing_replay.episode_log import load_episode_log, save_episode_log  # noqa: E402
from crossing_replay.episodes import Frame, make_policy, run_episode  # noqa: E402
from crossing_replay.errors import ReplayError  # noqa: E402
from crossing_replay.recorder import (  # noqa: E402
    EpisodeRecorder,
    RecordSummary,
    box_corners,
    open_recording,
    record_episode,
    replay_episode_log,
)
from crossing_replay.scene import _load_predictor, record_scene  # noqa: E402
from rollout import make_env  # noqa: E402
from scenarios.config import ScenarioConfig  # noqa: E402

SCENARIO = "busy_zebra"
FRAME_ENTITIES = ("/world/ego", "/world/vehicles", "/world/pedestrians", "/metrics/ego_speed")
STATIC_ENTITIES = (
    "/world/road/surface",
    "/world/road/sidewalks",
    "/world/road/kerbs",
    "/world/road/markings",
    "/world/road/stop_lines",
    "/world/crossing/stripes",
)
DATA_ROOT = Path(os.environ.get("CROSSING_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))


def read_rrd(path: Path) -> dict[str, list[dict]]:
    """Rows of every entity, as dicts without `log_time`, sorted by step (static rows first)."""
    rows: dict[str, list[dict]] = defaultdict(list)
    for chunk in RrdReader(str(path)).stream().to_chunks():
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if n not in ("log_time", "rerun.controls.RowId")]
        table = batch.select(names).to_pylist()
        rows[chunk.entity_path].extend(table)
    for entity in rows:
        rows[entity].sort(key=lambda r: -1 if r.get("step") is None else r["step"])
    return dict(rows)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RecordSummary]:
    out = tmp_path_factory.mktemp("rec") / "episode.rrd"
    summary = record_episode(out, SCENARIO, seed=1, policy="random", max_steps=30, keep_ground_truth=True)
    return out, summary


def test_record_entities_and_row_counts(recorded: tuple[Path, RecordSummary]) -> None:
    out, summary = recorded
    assert summary.steps == 30
    data = read_rrd(out)
    stores = RrdReader(str(out)).recordings()
    assert stores[0].application_id == "crossing_env"
    for entity in STATIC_ENTITIES:
        assert len(data[entity]) == 1, entity
        assert data[entity][0].get("step") is None  # static: no timeline
    for entity in FRAME_ENTITIES:
        assert len(data[entity]) == summary.steps + 1, entity  # frame 0 (reset) + one per step
        assert [r["step"] for r in data[entity]] == list(range(summary.steps + 1))
    # Pedestrian positions and labels are the ground truth's, frame by frame.
    for row, gt in zip(data["/world/pedestrians"], summary.ground_truths, strict=True):
        pos = np.asarray(row["Points2D:positions"], dtype=np.float64).reshape(-1, 2)
        np.testing.assert_allclose(pos, gt.pedestrian_positions, atol=1e-4)
        assert row["Points2D:labels"] == [str(i) for i in gt.pedestrian_ids]
    # Ego outline: closed 4-corner strip centred on the ego.
    for row, gt in zip(data["/world/ego"], summary.ground_truths, strict=True):
        strip = np.asarray(row["LineStrips2D:strips"][0])
        assert strip.shape == (5, 2)
        np.testing.assert_allclose(strip[0], strip[-1])
        np.testing.assert_allclose(strip[:4].mean(axis=0), gt.ego_position, atol=1e-4)
    speeds = [r["Scalars:scalars"][0] for r in data["/metrics/ego_speed"]]
    np.testing.assert_allclose(speeds, [float(np.hypot(*gt.ego_velocity)) for gt in summary.ground_truths])
    # Time: sim_time is step · dt.
    times = [r["sim_time"] for r in data["/world/ego"]]
    assert times[3].total_seconds() == pytest.approx(0.3)


def test_rrd_verify(recorded: tuple[Path, RecordSummary]) -> None:
    exe = shutil.which("rerun")
    if exe is None:
        pytest.skip("the rerun CLI is not on PATH")
    proc = subprocess.run(
        [exe, "rrd", "verify", str(recorded[0])],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ, CI="true"),
    )
    assert proc.returncode == 0, proc.stderr
    assert "verified without error" in proc.stdout + proc.stderr


def test_box_corners_rotate() -> None:
    c = box_corners(np.array([[10.0, 5.0]]), np.array([[4.0, 2.0]]), np.array([np.pi / 2]))[0]
    assert c.shape == (5, 2)
    np.testing.assert_allclose(c[:4].min(axis=0), [9.0, 3.0], atol=1e-12)  # length now along y
    np.testing.assert_allclose(c[:4].max(axis=0), [11.0, 7.0], atol=1e-12)


def test_predictions_logged_in_world_frame(tmp_path: Path) -> None:
    pytest.importorskip("predictors.trajectory_wrapper")
    out = tmp_path / "pred.rrd"
    summary = record_episode(out, SCENARIO, seed=1, max_steps=12, predictor="cvm", keep_ground_truth=True)
    rows = read_rrd(out)["/world/predictions"]
    assert len(rows) == summary.steps + 1
    last, gt = rows[-1], summary.ground_truths[-1]
    strips = [np.asarray(s) for s in last["LineStrips2D:strips"]]
    assert strips and all(s.shape == (13, 2) for s in strips)  # current position + 12 predicted
    # Each strip starts at its pedestrian's true position (world frame, not ego frame).
    by_id = dict(zip(gt.pedestrian_ids.tolist(), gt.pedestrian_positions, strict=True))
    for label, strip in zip(last["LineStrips2D:labels"], strips, strict=True):
        np.testing.assert_allclose(strip[0], by_id[int(label)], atol=1e-4)


def test_intention_logged_per_pedestrian(tmp_path: Path) -> None:
    import gymnasium as gym

    class FakeIntention(gym.ObservationWrapper):
        """Adds crossing_intention = 0.25 for every present slot."""

        def __init__(self, env: gym.Env) -> None:
            super().__init__(env)
            k = env.observation_space["pedestrians"].shape[0]
            box = gym.spaces.Box(0.0, 1.0, (k,), np.float32)
            self.observation_space = gym.spaces.Dict(
                {**env.observation_space.spaces, "crossing_intention": box}
            )

        def observation(self, obs: dict) -> dict:
            return {**obs, "crossing_intention": (obs["pedestrians"][:, 0] * 0.25).astype(np.float32)}

    env = FakeIntention(make_env(SCENARIO)[0])
    out = tmp_path / "i.rrd"
    with open_recording(out, "intention-test") as rec:
        recorder = EpisodeRecorder(rec, env.unwrapped.scenario, 0.1)
        frames = list(run_episode(env, 1, make_policy("constant", 1), max_steps=10))
        for frame in frames:
            recorder.log_frame(frame)
    env.close()
    seen: set[int] = set()
    for frame in frames:
        ids = frame.slot_ids[frame.slot_ids >= 0]
        assert set(ids.tolist()) <= set(frame.ground_truth.pedestrian_ids.tolist())  # slots map to real ids
        seen |= set(ids.tolist())
    data = read_rrd(out)
    assert seen and {e for e in data if e.startswith("/intention/")} == {f"/intention/ped_{i}" for i in seen}
    assert all(r["Scalars:scalars"] == [0.25] for e in data if e.startswith("/intention/") for r in data[e])


def test_episode_log_round_trip_is_bit_exact(tmp_path: Path) -> None:
    first = record_episode(
        tmp_path / "a.rrd", SCENARIO, seed=3, policy="random", max_steps=40, keep_ground_truth=True
    )
    log = save_episode_log(
        tmp_path / "ep.json",
        scenario=SCENARIO,
        seed=3,
        actions=first.actions,
        policy="random",
        final_ground_truth=first.final_ground_truth,
        metadata={"note": "test"},
    )
    loaded = load_episode_log(log)
    assert loaded.seed == 3 and loaded.policy == "random" and loaded.metadata == {"note": "test"}
    np.testing.assert_array_equal(loaded.actions, first.actions)
    second, match = replay_episode_log(log, tmp_path / "b.rrd", keep_ground_truth=True)
    assert match is True
    assert second.steps == first.steps == 40
    assert len(second.ground_truths) == len(first.ground_truths)
    assert all(a == b for a, b in zip(first.ground_truths, second.ground_truths, strict=True))
    # Both recordings hold the same data (log_time aside).
    a, b = read_rrd(tmp_path / "a.rrd"), read_rrd(tmp_path / "b.rrd")
    for entity in (*FRAME_ENTITIES, "/world/road/surface"):
        assert a[entity] == b[entity], entity


def test_episode_log_digest_mismatch_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    first = record_episode(tmp_path / "a.rrd", SCENARIO, seed=2, policy="random", max_steps=10)
    actions = first.actions.copy()
    actions[5] = -actions[5] if actions[5, 0] != 0 else 0.5
    log = save_episode_log(
        tmp_path / "ep.json",
        scenario=SCENARIO,
        seed=2,
        actions=actions,
        final_ground_truth=first.final_ground_truth,
    )
    assert main(["episode", str(log), "--out", str(tmp_path / "b.rrd")]) == 1
    assert "final_ground_truth_sha256" in capsys.readouterr().err


def test_episode_log_inline_scenario(tmp_path: Path) -> None:
    pytest.importorskip("scenarios")
    cfg = ScenarioConfig(name="inline_case", duration=5.0)
    log = save_episode_log(tmp_path / "ep.json", scenario=cfg, seed=0, actions=np.zeros((3, 1)))
    loaded = load_episode_log(log)
    assert loaded.scenario == cfg
    assert json.loads(log.read_text())["scenario"]["toml"]


def test_cli_record_and_episode(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, log = tmp_path / "c.rrd", tmp_path / "c.json"
    rc = main(
        [
            "record",
            "--scenario",
            SCENARIO,
            "--policy",
            "constant",
            "--seed",
            "0",
            "--steps",
            "8",
            "--out",
            str(out),
            "--save-log",
            str(log),
        ]
    )
    assert rc == 0 and out.is_file()
    data = json.loads(log.read_text())
    assert data["actions"] == [[0.0]] * 8 and data["policy"] == "constant"
    assert main(["episode", str(log), "--out", str(tmp_path / "d.rrd")]) == 0
    assert len(read_rrd(tmp_path / "d.rrd")["/world/pedestrians"]) == 9
    assert "8 steps" in capsys.readouterr().out


def test_view_spawns_the_viewer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[list[str]] = []

    class FakePopen:
        def __init__(self, cmd: list[str], **kwargs: object) -> None:
            calls.append(cmd)

    monkeypatch.setattr(subprocess, "Popen", FakePopen)
    out = tmp_path / "v.rrd"
    assert main(["record", "--scenario", SCENARIO, "--steps", "3", "--out", str(out), "--view"]) == 0
    assert len(calls) == 1 and calls[0][-1] == str(out) and Path(calls[0][0]).name.startswith("rerun")


def test_builtin_policies() -> None:
    obs: dict = {}
    np.testing.assert_array_equal(make_policy("constant", 0)(obs), [0.0])
    a = [make_policy("random", 7)(obs)[0] for _ in range(1)]
    p1, p2 = make_policy("random", 7), make_policy("random", 7)
    s1, s2 = [p1(obs)[0] for _ in range(5)], [p2(obs)[0] for _ in range(5)]
    assert s1 == s2 and len(set(s1)) == 5 and all(-1 <= v <= 1 for v in s1) and a[0] == s1[0]
    with pytest.raises(ReplayError, match="no_such_policy"):
        make_policy("no_such_policy", 0)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["record", "--scenario", "no_such_scenario", "--out", "{out}"], "no_such_scenario"),
        # a misspelt name blames --scenario, suggests the name and names no file that does not exist
        (
            ["record", "--scenario", "zebra_cse1", "--out", "{out}"],
            "--scenario: unknown scenario 'zebra_cse1'",
        ),
        (["video", "--scenario", "zebra_cse1", "--out", "{dir}/x.gif"], "did you mean 'zebra_case1'"),
        (["record", "--scenario", SCENARIO, "--policy", "nope", "--out", "{out}"], "nope"),
        (["record", "--scenario", SCENARIO, "--out", "{dir}/x.txt"], ".rrd"),
        (["record", "--scenario", SCENARIO, "--out", "{dir}/missing/x.rrd"], "does not exist"),
        (["episode", "{dir}/absent.json", "--out", "{out}"], "absent.json"),
    ],
)
def test_cli_bad_input_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    out = tmp_path / "bad.rrd"
    args = [a.format(out=out, dir=tmp_path) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "error" in err and message in err
    assert "--policy 'constant'" not in err and "zebra_cse1.toml" not in err
    assert list(tmp_path.iterdir()) == []  # nothing written, no temporary left behind


@pytest.mark.parametrize(
    "argv",
    [
        ["record", "--scenario", SCENARIO, "--seed", "-1", "--out", "x.rrd"],
        ["record", "--scenario", SCENARIO, "--steps", "0", "--out", "x.rrd"],
        ["scene", "--dataset", "mars", "--out", "x.rrd"],
        ["frobnicate"],
    ],
)
def test_cli_bad_arguments_exit_2(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2


@pytest.mark.parametrize(
    ("content", "field"),
    [
        ("{not json", "not valid JSON"),
        ('{"format": "other", "version": 1}', "'format'"),
        (
            '{"format": "crossing-env-episode-log", "version": 1, "scenario": "busy_zebra", "seed": 0}',
            "'actions'",
        ),
        (
            '{"format": "crossing-env-episode-log", "version": 1, "scenario": "busy_zebra", "seed": -3, '
            '"actions": []}',
            "'seed'",
        ),
        (
            '{"format": "crossing-env-episode-log", "version": 1, "scenario": "busy_zebra", "seed": 0, '
            '"actions": [[0.1], [4.0]]}',
            "'actions[1]'",
        ),
        (
            '{"format": "crossing-env-episode-log", "version": 1, "scenario": "busy_zebra", "seed": 0, '
            '"actions": [], "env_config": {"dt": 0.1, "warp": 9}}',
            "warp",
        ),
    ],
)
def test_bad_episode_logs_name_the_field(tmp_path: Path, content: str, field: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(ReplayError, match=re.escape(field)) as exc:
        load_episode_log(path)
    assert "bad.json" in str(exc.value)


def test_failed_recording_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    original = EpisodeRecorder.log_frame

    def failing(self: EpisodeRecorder, frame: Frame) -> None:
        if frame.step == 5:
            raise RuntimeError("simulated crash")
        original(self, frame)

    monkeypatch.setattr(EpisodeRecorder, "log_frame", failing)
    with pytest.raises(RuntimeError, match="simulated crash"):
        record_episode(tmp_path / "x.rrd", SCENARIO, seed=0, max_steps=20)
    assert list(tmp_path.iterdir()) == []


needs_data = pytest.mark.skipif(
    not (DATA_ROOT / "eth_ucy" / "eth" / "test").is_dir(),
    reason=f"ETH/UCY data not found at {DATA_ROOT} (set CROSSING_DATA)",
)


@pytest.fixture(scope="module")
def tiny_weights(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An untrained S-CGRU checkpoint, so the learned-model path runs whether or not weights ship."""
    torch = pytest.importorskip("torch")
    models = pytest.importorskip("predictors.models")
    train = pytest.importorskip("predictors.train")
    torch.manual_seed(0)
    folder = tmp_path_factory.mktemp("weights")
    cfg = models.ModelConfig(kind="s-cgru", hidden_size=16, embed_size=8)
    train.save_checkpoint(folder / "s-cgru_eth.pt", models.SocialRecurrent(cfg), {"note": "test"})
    return folder


@pytest.mark.data
@needs_data
@pytest.mark.parametrize("model", ["s-cgru", "cvm", "s-cgru-shipped"])
def test_scene_replay_small_slice(tmp_path: Path, model: str, tiny_weights: Path) -> None:
    pytest.importorskip("predictors.data")
    out = tmp_path / "scene.rrd"
    weights = tiny_weights if model == "s-cgru" else None
    summary = record_scene(
        out, "eth", DATA_ROOT, model=model.removesuffix("-shipped"), max_frames=40, weights_dir=weights
    )
    assert summary.frames == 40 and summary.predictions > 0
    assert np.isfinite(summary.ade) and 0 < summary.ade < summary.fde + 1e-9 < 50
    if model == "cvm":
        assert summary.predictor == "cvm"
    elif model == "s-cgru":
        assert summary.predictor == "s-cgru (s-cgru_eth.pt)"
    else:  # the shipped weights (predictors/weights/s-cgru_eth.pt), never a silent fallback
        from predictors.checkpoints import WEIGHTS_DIR

        assert (WEIGHTS_DIR / "s-cgru_eth.pt").is_file()
        assert summary.predictor == "s-cgru (s-cgru_eth.pt)"
    data = read_rrd(out)
    assert len(data["/scene/pedestrians"]) == 40
    assert len(data["/scene/prediction"]) == 40
    assert summary.predictor in data["/info"][0]["TextLog:text"][0]
    strips = [np.asarray(s) for r in data["/scene/prediction"] for s in r["LineStrips2D:strips"]]
    assert len(strips) == summary.predictions
    assert all(s.shape == (13, 2) for s in strips)  # current position + 12 predicted


def test_constant_velocity_fallback_extrapolates() -> None:
    predict, label = _load_predictor("s-cgru", "eth", "/nonexistent", allow_fallback=True)
    assert "constant velocity" in label
    obs = np.stack([np.stack([np.arange(8.0), 2 * np.arange(8.0)], axis=1)]).astype(np.float32)
    out = np.asarray(predict(obs, None))
    np.testing.assert_allclose(out[0, -1], [7.0 + 12, 14.0 + 24], atol=1e-5)


@pytest.mark.data
@needs_data
def test_scene_bad_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(
        [
            "scene",
            "--dataset",
            "eth",
            "--data",
            str(DATA_ROOT),
            "--file",
            "nope.txt",
            "--out",
            str(tmp_path / "s.rrd"),
        ]
    )
    assert rc == 2 and "nope.txt" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_scene_missing_data_root_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(
        ["scene", "--dataset", "eth", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "s.rrd")]
    )
    assert rc == 2 and "CROSSING_DATA" in capsys.readouterr().err
