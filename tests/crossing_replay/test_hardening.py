"""crossing-replay hardening and video (issue 16): clear errors, no silent fallbacks, MP4/GIF, rerun plots."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rerun")
from crossing_env import safety
from crossing_env.types import GroundTruth
from crossing_replay.cli import main
from crossing_replay.episode_log import save_episode_log
from crossing_replay.errors import ReplayError
from crossing_replay.recorder import record_episode
from crossing_replay.scene import _load_predictor
from crossing_replay.video import hold_frames
from crossing_replay.viewer import verify_recording
from tests.crossing_replay.test_replay import read_rrd


@pytest.fixture(scope="module")
def small_rrd(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("rrd") / "ep.rrd"
    record_episode(out, "busy_zebra", seed=2, policy="constant", max_steps=25)
    return out


def test_corrupt_recordings_are_refused_before_a_viewer_starts(small_rrd: Path, tmp_path: Path, capsys):
    verify_recording(small_rrd)
    data = bytearray(small_rrd.read_bytes())
    mid = len(data) // 2
    data[mid : mid + 64] = bytes(b ^ 0xFF for b in data[mid : mid + 64])
    flipped, garbage = tmp_path / "flipped.rrd", tmp_path / "garbage.rrd"
    flipped.write_bytes(bytes(data))
    garbage.write_bytes(b"not a recording at all")
    for bad, needle in ((flipped, "corrupt recording"), (garbage, "not a rerun recording")):
        assert main(["screenshot", str(bad), "--out", str(tmp_path / "shot.png")]) == 2
        err = capsys.readouterr().err
        assert needle in err and str(bad) in err and err.count("\n") == 1
    assert not (tmp_path / "shot.png").exists()


def _expected_ttc(gt: GroundTruth) -> float:
    """The closest ego-pedestrian TTC computed here from the ground truth; NaN where it is undefined."""
    if gt.pedestrian_ids.size == 0:
        return math.nan
    length, width = gt.ego_size
    ttc = safety.box_circle_ttc(
        gt.ego_position,
        gt.ego_velocity,
        length,
        width,
        gt.pedestrian_positions,
        gt.pedestrian_velocities,
        gt.pedestrian_radii,
    )
    best = float(np.min(ttc))
    return best if math.isfinite(best) else math.nan


def test_rerun_metrics_have_one_unit_per_plot_and_break_at_gaps(tmp_path: Path):
    out = tmp_path / "ep.rrd"
    summary = record_episode(
        out, "busy_zebra", seed=2, policy="constant", max_steps=25, keep_ground_truth=True
    )
    data = read_rrd(out)
    ttc = [r["Scalars:scalars"][0] for r in data["/metrics/ttc"]]
    expected = [_expected_ttc(gt) for gt in summary.ground_truths]
    assert len(ttc) == len(expected) == summary.steps + 1  # one value per frame
    # This episode has frames without a pedestrian or a closing course (NaN: the line breaks there) and
    # frames with a finite TTC; each frame logs exactly the value computed from its ground truth.
    assert any(math.isnan(v) for v in expected) and any(math.isfinite(v) for v in expected)
    assert [math.isnan(v) for v in ttc] == [math.isnan(v) for v in expected]
    np.testing.assert_allclose(
        [v for v in ttc if math.isfinite(v)], [v for v in expected if math.isfinite(v)], rtol=1e-9
    )
    from crossing_replay.recorder import METRIC_PLOTS, episode_blueprint
    from scenarios import load_scenario

    assert {name for name, _ in METRIC_PLOTS} == {"ego_speed", "ego_acceleration", "min_distance", "ttc"}
    assert all("(" in title for _, title in METRIC_PLOTS)  # each plot names its unit
    episode_blueprint(load_scenario("busy_zebra"), intention=True)  # builds with rerun's blueprint API


def test_scene_model_errors_instead_of_silent_fallback():
    with pytest.raises(ReplayError, match="unknown"):
        _load_predictor("foo", "eth")
    with pytest.raises(ReplayError, match="--fallback-cvm"):
        _load_predictor("s-cgru", "eth", "/nonexistent")
    _, label = _load_predictor("s-cgru", "eth", "/nonexistent", allow_fallback=True)
    assert "fallback" in label
    with pytest.raises(SystemExit) as exc:
        main(["scene", "--dataset", "eth", "--model", "foo", "--out", "x.rrd"])
    assert exc.value.code == 2


def test_episode_whose_predictor_fails_is_an_error_unless_opted_out(tmp_path: Path, capsys):
    log = tmp_path / "ep.json"
    save_episode_log(
        log,
        scenario="zebra_case1",
        seed=0,
        actions=np.zeros((5, 1), np.float32),
        policy="constant",
        predictor=str(tmp_path / "missing.pt"),
    )
    out = tmp_path / "ep.rrd"
    assert main(["episode", str(log), "--out", str(out)]) == 2
    assert "--without-predictors" in capsys.readouterr().err
    assert not out.exists()
    # The log carries no final-state digest and all 5 actions run, so the replay cannot differ: exit 0.
    assert main(["episode", str(log), "--out", str(out), "--without-predictors"]) == 0
    err = capsys.readouterr().err
    assert "replaying without predictor wrappers" in err and "differs" not in err
    assert out.is_file()
    assert len(read_rrd(out)["/world/ego"]) == 6  # frame 0 plus the 5 logged actions


def test_record_accepts_intention_none(tmp_path: Path):
    out = tmp_path / "r.rrd"
    argv = ["record", "--scenario", "zebra_case1", "--policy", "yielding", "--steps", "3"]
    assert main([*argv, "--predictor", "none", "--intention", "none", "--out", str(out)]) == 0
    assert not any(e.startswith("/intention") for e in read_rrd(out))


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_video_writes_every_frame(tmp_path: Path, suffix: str):
    iio = pytest.importorskip("imageio.v3")
    if suffix == ".mp4":
        pytest.importorskip("imageio_ffmpeg")
    out = tmp_path / f"ep{suffix}"
    argv = ["video", "--scenario", "busy_zebra", "--policy", "constant_speed", "--steps", "7"]
    assert main([*argv, "--predictor", "cvm", "--intention", "none", "--out", str(out)]) == 0
    frames = iio.imread(out, index=None)
    held = hold_frames(10)  # the last frame is held for a second at the default 10 fps
    assert frames.shape[-1] == 3
    if suffix == ".gif":  # Pillow merges repeated frames into a longer last one
        from PIL import Image

        with Image.open(out) as gif:
            gif.seek(7)
            assert frames.shape[0] == 8 and gif.info["duration"] == 100 * (1 + held)
    else:
        assert frames.shape[0] == 8 + held
        last = frames[7].astype(np.int16)
        assert np.abs(frames[-1] - last).mean() < 1.0  # the held copy (MP4 is lossy: nearly equal)
        assert np.abs(frames[-1] - last).mean() < np.abs(frames[6] - last).mean()  # the episode moved
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_video_refuses_an_unknown_format(tmp_path: Path, capsys):
    assert main(["video", "--scenario", "busy_zebra", "--out", str(tmp_path / "ep.avi")]) == 2
    assert ".mp4 or .gif" in capsys.readouterr().err


def test_gymnasium_record_video_works(tmp_path: Path):
    pytest.importorskip("moviepy")
    import gymnasium as gym
    from gymnasium.wrappers import RecordVideo

    from crossing_env import ENV_ID

    env = gym.make(ENV_ID, scenario="zebra_case1", render_mode="rgb_array")
    env = RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.array([0.0], np.float32))
    env.close()
    assert [p.suffix for p in (tmp_path / "videos").iterdir()] == [".mp4"]


def test_scene_opens_on_a_populated_frame(tmp_path: Path):
    pytest.importorskip("predictors.data")
    from crossing_replay.scene import populated_start

    lines = []
    for f in range(20):
        crowd = 1 if f < 7 else 4  # nearly empty at first, as ETH's first frames
        lines += [f"{f * 10}\t{p + 1}.0\t{0.4 * f:.2f}\t{p:.2f}" for p in range(crowd)]
    path = tmp_path / "scene.txt"
    path.write_text("\n".join(lines) + "\n")
    assert populated_start(path) == 7


def test_intention_series_are_coloured_by_state(tmp_path: Path):
    pytest.importorskip("predictors.intention")
    from crossing_replay.recorder import PED_COLOURS

    out = tmp_path / "i.rrd"
    argv = ["record", "--scenario", "busy_zebra", "--policy", "constant", "--steps", "15"]
    assert main([*argv, "--predictor", "none", "--intention", "classical", "--out", str(out)]) == 0
    data = read_rrd(out)
    colours = {
        int(c)
        for e, rows in data.items()
        if e.startswith("/intention/")
        for r in rows
        for c in (r.get("SeriesLines:colors") or [])
    }
    packed = {(r << 24) | (g << 16) | (b << 8) | 255 for r, g, b in PED_COLOURS.values()}
    assert colours and colours <= packed
