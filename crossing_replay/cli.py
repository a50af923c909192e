"""`crossing-replay`: write crossing episodes and real pedestrian scenes to rerun recordings (`.rrd`).

Subcommands:

* ``record --scenario NAME --policy NAME --seed N --out episode.rrd [--steps N] [--predictor M]
  [--intention qlb|classical] [--save-log LOG.json] [--view]`` runs one episode of
  ``crossing_env/Crossing-v0`` through `rollout` and logs it. Policies come from ``agents.make_policy``
  (``constant`` and ``random`` included); a policy that reads predictions gets the default wrappers (QLB,
  S-CGRU) unless ``--predictor`` / ``--intention`` say otherwise, and one that cannot load is an error;
* ``episode LOG.json --out episode.rrd`` re-runs an episode saved with `save_episode_log` (the format the
  evaluation script writes for its worst episodes) and logs it the same way;
* ``scene --dataset eth|hotel|univ|zara1|zara2|sdd [--file F] --out scene.rrd [--model s-cgru]`` replays a
  real ETH/UCY or SDD recording with trajectory predictions drawn against the ground truth (constant
  velocity, announced in the recording, when the learned model's weights are missing);
* ``screenshot REC.rrd --time T --out shot.png`` saves a PNG of the viewer at ``sim_time = T`` without a
  display (headless viewer; needs a Vulkan driver such as Mesa's lavapipe).

``--view`` starts the native viewer shipped in the rerun-sdk wheel on the written file. Bad input exits
with code 2 and a message naming the file, field or option; recordings are written to a temporary file
and renamed, so a failed run leaves no partial ``.rrd``.

The recordings' entities are listed in `crossing_replay.recorder`, the episode-log format in
`crossing_replay.episode_log`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from crossing_common.cli import DefaultsHelpFormatter
from crossing_replay.episode_log import save_episode_log
from crossing_replay.episodes import INTENTION_WRAPPERS
from crossing_replay.errors import ReplayError
from crossing_replay.recorder import record_episode, replay_episode_log
from crossing_replay.scene import DATASETS, SCENE_MODELS, record_scene
from crossing_replay.viewer import open_viewer, screenshot


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from exc
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {value}")
    return value


def _positive_int(text: str) -> int:
    value = _non_negative_int(text)
    if value == 0:
        raise argparse.ArgumentTypeError("expected a positive integer, got 0")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The `crossing-replay` argument parser."""
    fmt = DefaultsHelpFormatter
    p = argparse.ArgumentParser(
        prog="crossing-replay",
        description="Write crossing episodes and real pedestrian scenes to rerun recordings (.rrd) or"
        " videos; --view opens recordings in the rerun viewer.",
        formatter_class=fmt,
    )
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("record", help="run an episode and record it", formatter_class=fmt)
    r.add_argument("--scenario", required=True, help="built-in scenario name or scenario TOML path")
    r.add_argument("--policy", default="constant", help="policy (agents.make_policy, or constant/random)")
    r.add_argument("--seed", type=_non_negative_int, default=0, help="reset seed")
    r.add_argument("--out", required=True, help="output .rrd")
    r.add_argument("--steps", type=_positive_int, default=None, help="stop after this many steps")
    r.add_argument(
        "--predictor",
        default=None,
        help="trajectory predictor wrapper: cvm, s-cgru, ... or a checkpoint path; 'none' for no wrapper"
        " (default: s-cgru for a policy that reads predictions, else none; one that cannot load is an error)",
    )
    r.add_argument(
        "--intention",
        default=None,
        choices=[*sorted(INTENTION_WRAPPERS), "none"],
        help="intention wrapper; 'none' for no wrapper (default: as for --predictor)",
    )
    r.add_argument("--save-log", default=None, help="also write the episode log (JSON) here")
    r.add_argument("--view", action="store_true", help="open the recording in the rerun viewer")
    e = sub.add_parser("episode", help="replay a saved episode log", formatter_class=fmt)
    e.add_argument("log", help="episode log (.json) written by save_episode_log")
    e.add_argument("--out", required=True, help="output .rrd")
    e.add_argument(
        "--without-predictors",
        action="store_true",
        help="replay without the log's predictor wrappers when they cannot be loaded here (else an error)",
    )
    e.add_argument("--view", action="store_true", help="open the recording in the rerun viewer")
    s = sub.add_parser(
        "scene", help="replay a real ETH/UCY or SDD scene with predictions", formatter_class=fmt
    )
    s.add_argument("--dataset", required=True, choices=DATASETS, help="which recording set to replay")
    s.add_argument("--file", default=None, help="trajectory file (path or name in the dataset's test folder)")
    s.add_argument(
        "--data", default=None, help="data root (default: $CROSSING_DATA or <repo>/../shared/data)"
    )
    s.add_argument(
        "--model", default="s-cgru", choices=[*SCENE_MODELS, "cvm", "kalman"], help="trajectory predictor"
    )
    s.add_argument(
        "--weights", default=None, help="folder of <model>_<dataset>.pt (default: predictors/weights)"
    )
    s.add_argument(
        "--fallback-cvm",
        action="store_true",
        help="use constant velocity (announced in the recording) when the model's weights are missing",
    )
    s.add_argument(
        "--start-frame",
        type=_non_negative_int,
        default=None,
        help="first frame index of the slice (default: the first frame with half the peak crowd)",
    )
    s.add_argument("--max-frames", type=_positive_int, default=None, help="number of frames to replay")
    s.add_argument("--out", required=True, help="output .rrd")
    s.add_argument("--view", action="store_true", help="open the recording in the rerun viewer")
    g = sub.add_parser(
        "screenshot",
        help="PNG of the viewer showing a recording (headless, needs Vulkan)",
        formatter_class=fmt,
    )
    g.add_argument("rrd", help="recording (.rrd); checked with `rerun rrd verify` first")
    g.add_argument("--out", required=True, help="output .png")
    g.add_argument("--time", type=float, default=0.0, help="sim_time to show, seconds")
    g.add_argument("--port", type=_positive_int, default=9877, help="gRPC port of the headless viewer")
    g.add_argument("--max-kb", type=_positive_int, default=500, help="downscale until the PNG is this small")
    v = sub.add_parser("video", help="render an episode (or a saved log) to MP4 or GIF", formatter_class=fmt)
    src = v.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", help="built-in scenario name or scenario TOML path")
    src.add_argument("--log", help="episode log (.json) to re-run, e.g. from crossing-eval's worst/")
    v.add_argument("--policy", default="yielding", help="policy when --scenario is given")
    v.add_argument("--seed", type=_non_negative_int, default=0, help="reset seed when --scenario is given")
    v.add_argument("--steps", type=_positive_int, default=None, help="stop after this many steps")
    v.add_argument("--predictor", default=None, help="as for record (drawn on the frames)")
    v.add_argument(
        "--intention", default=None, choices=[*sorted(INTENTION_WRAPPERS), "none"], help="as for record"
    )
    v.add_argument("--out", required=True, help="output .mp4 (H.264 via imageio-ffmpeg) or .gif")
    v.add_argument("--fps", type=_positive_int, default=10, help="frames per second of the video")
    return p


def _none(value: str | None) -> str | None:
    """'none' on the command line means: no wrapper (None means: the default choice)."""
    return "" if value == "none" else value


def _record(args: argparse.Namespace) -> int:
    summary = record_episode(
        args.out,
        args.scenario,
        args.seed,
        policy=args.policy,
        max_steps=args.steps,
        predictor=_none(args.predictor),
        intention=_none(args.intention),
    )
    if args.save_log:
        save_episode_log(
            args.save_log,
            scenario=args.scenario,
            seed=args.seed,
            actions=summary.actions,
            policy=args.policy,
            predictor=summary.predictor or None,
            intention=summary.intention or None,
            final_ground_truth=summary.final_ground_truth,
        )
    print(f"wrote {summary.out}: {summary.steps} steps, {summary.collisions} collision(s)")
    return 0


def _episode(args: argparse.Namespace) -> int:
    """Replay a log; 1 (with a warning) when the replay differs from it."""
    summary, match = replay_episode_log(args.log, args.out, without_predictors=args.without_predictors)
    print(f"wrote {summary.out}: {summary.steps} steps, {summary.collisions} collision(s)")
    if match is False:
        print(
            f"crossing-replay: warning: {args.log}: the replay differs from the log (episode "
            "length vs field 'actions', or final ground truth vs field 'final_ground_truth_sha256'): "
            "the code or the scenario changed since it was saved",
            file=sys.stderr,
        )
        return 1
    return 0


def _scene(args: argparse.Namespace) -> int:
    sc = record_scene(
        args.out,
        args.dataset,
        args.data,
        args.file,
        args.model,
        args.start_frame,
        args.max_frames,
        args.weights,
        allow_fallback=args.fallback_cvm,
    )
    print(
        f"wrote {sc.out}: {sc.file.name}, {sc.frames} frames, {sc.predictions} predictions, "
        f"predictor {sc.predictor}, ADE {sc.ade:.3f} m, FDE {sc.fde:.3f} m"
    )
    return 0


def _screenshot(args: argparse.Namespace) -> int:
    shot = screenshot(args.rrd, args.out, args.time, port=args.port, max_bytes=args.max_kb * 1000)
    print(f"wrote {shot} ({shot.stat().st_size // 1000} kB)")
    return 0


def _video(args: argparse.Namespace) -> int:
    from crossing_replay.video import record_video  # imageio only for this command

    summary = record_video(
        args.out,
        scenario=args.scenario,
        log=args.log,
        policy=args.policy,
        seed=args.seed,
        max_steps=args.steps,
        predictor=_none(args.predictor),
        intention=_none(args.intention),
        fps=args.fps,
    )
    print(f"wrote {summary.out}: {summary.frames} frames at {args.fps} fps")
    return 0


_COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "video": _video,
    "record": _record,
    "episode": _episode,
    "scene": _scene,
    "screenshot": _screenshot,
}
"""Subcommand → handler returning the exit status (bad input is raised, and reported by `main`)."""


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `crossing-replay`; returns 0 on success, 2 on bad input, 1 on a replay mismatch."""
    args = build_parser().parse_args(argv)
    try:
        status = _COMMANDS[args.command](args)
    except (ReplayError, ValueError, FileNotFoundError) as exc:
        print(f"crossing-replay: error: {exc}", file=sys.stderr)
        return 2
    if getattr(args, "view", False):  # `screenshot` has no --view
        open_viewer(Path(args.out))
    return status


if __name__ == "__main__":
    sys.exit(main())
