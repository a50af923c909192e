"""``crossing-replay video``: an episode rendered frame by frame to MP4 (H.264) or GIF.

Frames come from the env's top-down renderer (`crossing_env.render`), with the predictor wrappers'
paths and intentions drawn when they are on, the ego marked, a caption (scenario, policy, seed, time) and a
marker on a collision; the last frame is held for `HOLD_SECONDS`, so the end (often the collision) can be
seen. MP4 is written by imageio's ffmpeg plugin (the
``imageio-ffmpeg`` wheel bundles an ffmpeg binary; the ``video`` extra installs it), GIF by Pillow.
The file is written beside the target and renamed, so a failed run leaves nothing half-written.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crossing_common.files import atomic_output
from crossing_env.render import TopDownRenderer
from crossing_replay.episode_log import load_episode_log
from crossing_replay.episodes import env_for_policy, make_policy, run_episode
from crossing_replay.errors import VIDEO_HEADS, ReplayError, check_output

FORMATS = (".mp4", ".gif")
"""Video formats by file suffix."""
HOLD_SECONDS = 1.0
"""The last frame is repeated for this long at the end of a video."""


@dataclass(frozen=True)
class VideoSummary:
    """What a video run produced."""

    out: Path
    """The file written."""
    frames: int
    """Number of frames of the episode (the reset and every step; without the held copies of the last)."""


def _writer_check(out: Path) -> None:
    if out.suffix.lower() not in FORMATS:
        raise ReplayError(f"--out {str(out)!r}: the video must end in {' or '.join(FORMATS)}")
    if not out.parent.is_dir() and str(out.parent) != "":
        raise ReplayError(f"--out {str(out)!r}: folder {str(out.parent)!r} does not exist")
    check_output(out, VIDEO_HEADS, "a video")
    if out.suffix.lower() == ".mp4":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise ReplayError(
                "MP4 needs imageio-ffmpeg: pip install 'crossing-env[video]' (or write a .gif)"
            ) from None


def hold_frames(fps: int, seconds: float = HOLD_SECONDS) -> int:
    """Extra copies of the last frame that hold it for `seconds` at `fps` (at least one)."""
    return max(1, round(seconds * fps))


def write_video(
    frames: list[np.ndarray], out: str | os.PathLike[str], fps: int = 10, hold: float = HOLD_SECONDS
) -> Path:
    """Write uint8 (H, W, 3) frames as MP4 or GIF (by suffix), atomically; the last one held `hold` s."""
    import imageio.v3 as iio

    dst = Path(out)
    _writer_check(dst)
    if not frames:
        raise ReplayError("no frames to write")
    extra = hold_frames(fps, hold) if hold > 0 else 0
    stack = np.stack([*frames, *([frames[-1]] * extra)])
    with atomic_output(dst, suffix=dst.suffix) as tmp:
        if dst.suffix.lower() == ".gif":
            iio.imwrite(tmp, stack, extension=".gif", duration=1000.0 / fps, loop=0)
        else:
            # yuv420p needs even sizes; H.264 in yuv420p plays in every browser and player.
            h, w = stack.shape[1] - stack.shape[1] % 2, stack.shape[2] - stack.shape[2] % 2
            iio.imwrite(
                tmp,
                stack[:, :h, :w],
                plugin="FFMPEG",
                extension=".mp4",
                fps=fps,
                codec="libx264",
                macro_block_size=1,
                ffmpeg_log_level="error",
            )
    return dst


def record_video(
    out: str | os.PathLike[str],
    scenario: str | None = None,
    log: str | os.PathLike[str] | None = None,
    policy: str = "yielding",
    seed: int = 0,
    max_steps: int | None = None,
    predictor: str | None = None,
    intention: str | None = None,
    fps: int = 10,
) -> VideoSummary:
    """Run an episode (a policy on `scenario`, or the actions of an episode `log`) and write its video.

    Raises:
        ReplayError: bad arguments, an unreadable log, or wrappers that cannot be built.
    """
    _writer_check(Path(out))
    actions = None
    if log is not None:
        ep = load_episode_log(log)
        scenario, seed, policy, actions = ep.scenario, ep.seed, ep.policy, ep.actions
        predictor, intention = ep.predictor, ep.intention
    if scenario is None:
        raise ReplayError("give --scenario or --log")
    env, _, _ = env_for_policy(scenario, policy, predictor, intention, replaying=actions is not None)
    try:
        base = env.unwrapped
        renderer = TopDownRenderer(base.config, caption=f"policy {policy}   seed {seed}")
        pol = None if actions is not None else make_policy(policy, seed, env)
        frames = [
            renderer.draw(base.world, frame.observation)
            for frame in run_episode(env, seed, policy=pol, actions=actions, max_steps=max_steps)
        ]
    finally:
        env.close()
    return VideoSummary(write_video(frames, out, fps), len(frames))
