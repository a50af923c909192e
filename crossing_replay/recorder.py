"""Rerun recordings (`.rrd`) of simulated crossing episodes, from a policy or from an episode log.

Recordings are written to a temporary file and renamed, so a failed run leaves no partial ``.rrd``.

Entities of an episode recording (world coordinates in metres; the 2D view draws +y downwards, like
highway-env's renderer):

* static ``/world/road/{surface,sidewalks,kerbs,markings,stop_lines}`` and ``/world/crossing/stripes``;
* per frame ``/world/ego`` and ``/world/vehicles`` (oriented boxes as closed `LineStrips2D`: `Boxes2D` has no
  rotation), ``/world/pedestrians`` (`Points2D`, id labels, colours by `PedState`), ``/world/signal``,
  ``/world/predictions`` when the observation holds ``predicted_paths``;
* time series ``/metrics/{ego_speed,ego_acceleration,min_distance,ttc}`` and
  ``/intention/ped_<id>`` when the observation holds ``crossing_intention``;
* ``/events/collisions``, ``/events/background_collisions`` (background car–pedestrian contacts) and
  ``/events/behaviour`` (`TextLog`).

Frame ``i`` is logged at ``step = i`` and ``sim_time = i·dt`` seconds; frame 0 is the state after ``reset``,
so an episode of ``n`` steps has ``n + 1`` rows per per-frame entity.

``rerun`` is imported inside the functions that log: it takes most of a second to import, which
``crossing-replay --help`` and the episode-log readers should not pay.
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crossing_common.files import give_default_permissions
from crossing_env.observation import CROSSING_INTENTION_KEY
from crossing_env.types import GroundTruth
from crossing_replay.drawing import (
    EGO_COLOUR,
    METRIC_PLOTS,
    PED_COLOURS,
    PREDICTION_COLOUR,
    VEHICLE_COLOUR,
    EpisodeRecorder,
    box_corners,
)
from crossing_replay.episode_log import ground_truth_digest, load_episode_log
from crossing_replay.episodes import env_for_policy, make_policy, run_episode
from crossing_replay.errors import RRD_HEADS, ReplayError, check_output
from scenarios.config import EnvConfig, ScenarioConfig

APP_ID = "crossing_env"
__all__ = [
    "APP_ID",
    "EGO_COLOUR",
    "METRIC_PLOTS",
    "PED_COLOURS",
    "PREDICTION_COLOUR",
    "VEHICLE_COLOUR",
    "EpisodeRecorder",
    "RecordSummary",
    "box_corners",
    "episode_blueprint",
    "open_recording",
    "record_episode",
    "replay_episode_log",
]


@contextmanager
def open_recording(out: str | os.PathLike[str], recording_id: str, blueprint: Any = None) -> Iterator[Any]:
    """A `rerun.RecordingStream` writing to a temporary file that replaces `out` only on success."""
    import rerun as rr

    path = Path(out)
    if path.suffix != ".rrd":
        raise ReplayError(f"--out {str(path)!r}: the output must end in .rrd")
    if not path.parent.is_dir():
        raise ReplayError(f"--out {str(path)!r}: folder {str(path.parent)!r} does not exist")
    check_output(path, RRD_HEADS, "a rerun recording")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    rec = rr.RecordingStream(APP_ID, recording_id=recording_id)
    rec.set_sinks(rr.FileSink(tmp), default_blueprint=blueprint)
    try:
        yield rec
        rec.flush()
        rec.disconnect()
        give_default_permissions(tmp)
        os.replace(tmp, path)
    finally:
        rec.disconnect()
        if os.path.exists(tmp):
            os.unlink(tmp)


def episode_blueprint(scenario: ScenarioConfig, intention: bool = False) -> Any:
    """Viewer layout: the road around the crossing on top, metrics and events below.

    The side panels start collapsed so the road gets the room; the intention plot appears only when the
    observation holds ``crossing_intention``.
    """
    import rerun.blueprint as rrb

    road = scenario.road
    x = scenario.crossing.position
    margin = road.sidewalk_width + 1.0
    # One quantity (one unit) per plot: a shared axis squashed 0-90 m distances against 0-5 s TTCs.
    plots: list[Any] = [
        rrb.TimeSeriesView(origin=f"/metrics/{name}", name=title) for name, title in METRIC_PLOTS
    ]
    if intention:
        plots.append(
            rrb.TimeSeriesView(
                origin="/intention",
                name="crossing intention (colour = state)",
                axis_y=rrb.ScalarAxis(range=(0.0, 1.0)),
                plot_legend=rrb.PlotLegend(visible=False),
            )
        )
    plots.append(rrb.TextLogView(origin="/events", name="events"))
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Spatial2DView(
                origin="/world",
                name="crossing",
                background=(40, 44, 40),
                visual_bounds=rrb.VisualBounds2D(
                    x_range=[x - 35.0, x + 35.0], y_range=[-margin - 6.0, road.road_width + margin + 6.0]
                ),
            ),
            rrb.Horizontal(*plots),
            row_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline="sim_time", state="collapsed"),
    )


@dataclass(frozen=True)
class RecordSummary:
    """What a recording run produced."""

    out: Path
    """The `.rrd` written."""
    steps: int
    """Number of env steps (frames − 1)."""
    collisions: int
    """Number of ego collisions."""
    actions: np.ndarray
    """(T, 1) actions taken."""
    final_ground_truth: GroundTruth
    """Last ground truth."""
    ground_truths: tuple[GroundTruth, ...] = ()
    """Every frame's ground truth, when asked for (`keep_ground_truth=True`)."""
    predictor: str | None = None
    """Trajectory predictor wrapper really used."""
    intention: str | None = None
    """Intention wrapper really used."""


def record_episode(
    out: str | os.PathLike[str],
    scenario: str | os.PathLike[str] | ScenarioConfig,
    seed: int,
    policy: str = "constant",
    actions: np.ndarray | None = None,
    max_steps: int | None = None,
    predictor: str | None = None,
    env_config: EnvConfig | None = None,
    keep_ground_truth: bool = False,
    intention: str | None = None,
) -> RecordSummary:
    """Run one episode (with `policy`, or replaying `actions`) and write it to `out` (atomically).

    A policy that reads predictions gets `rollout`'s default wrappers (QLB intention, S-CGRU paths) when
    neither `predictor` nor `intention` is given; a wrapper that cannot be built is a `ReplayError`.
    """
    if max_steps is not None and max_steps < 1:
        raise ReplayError(f"--steps {max_steps}: must be at least 1")
    if seed < 0:
        raise ReplayError(f"--seed {seed}: must be non-negative")
    env, predictor, intention = env_for_policy(
        scenario, policy, predictor, intention, env_config, replaying=actions is not None
    )
    try:
        base = env.unwrapped
        pol = None if actions is not None else make_policy(policy, seed, env)
        name = base.scenario.name
        rid = f"{name}-{policy}-seed{seed}"
        taken: list[np.ndarray] = []
        gts: list[GroundTruth] = []
        collisions = 0
        with open_recording(
            out, rid, episode_blueprint(base.scenario, CROSSING_INTENTION_KEY in env.observation_space.spaces)
        ) as rec:
            rec.send_recording_name(f"{name} · policy {policy} · seed {seed}")
            recorder = EpisodeRecorder(rec, base.scenario, base.config.dt)
            recorder.log_static()
            gt = None
            for frame in run_episode(env, seed, pol, actions, max_steps):
                recorder.log_frame(frame)
                gt = frame.ground_truth
                collisions += len(gt.collisions)
                if keep_ground_truth:
                    gts.append(gt)
                if frame.action is not None:
                    taken.append(frame.action)
        assert gt is not None
    finally:
        env.close()
    acts = np.stack(taken) if taken else np.zeros((0, 1), np.float32)
    return RecordSummary(Path(out), len(taken), collisions, acts, gt, tuple(gts), predictor, intention)


def replay_episode_log(
    log_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    keep_ground_truth: bool = False,
    without_predictors: bool = False,
) -> tuple[RecordSummary, bool | None]:
    """Re-run a saved episode into `out`.

    The logged actions are replayed, so the predictor wrappers only add what is drawn (predicted paths,
    intentions). If they cannot be built here that is an error (the recording would silently lack what the
    policy saw), unless `without_predictors` (``--without-predictors``) asks to replay without them.

    Raises:
        ReplayError: a bad log, or wrappers that fail to load without `without_predictors`.

    Returns:
        The summary, and whether the replay matched the log (None: the log has no digest). A mismatch
        (other final ground truth, or an episode that ended before the actions ran out) means that the
        code or the scenario changed since the log was saved.
    """
    log = load_episode_log(log_path)
    kwargs: dict[str, Any] = {
        "policy": log.policy,
        "actions": log.actions,
        "env_config": log.env_config,
        "keep_ground_truth": keep_ground_truth,
    }
    try:
        summary = record_episode(
            out, log.scenario, log.seed, predictor=log.predictor, intention=log.intention, **kwargs
        )
    except ReplayError as exc:
        if log.predictor is None and log.intention is None:
            raise
        if not without_predictors:
            raise ReplayError(
                f"{log_path}: the episode's predictor wrappers cannot be built here ({exc}); give"
                " --without-predictors to replay it without them"
            ) from exc
        print(f"crossing-replay: {exc}; replaying without predictor wrappers", file=sys.stderr)
        summary = record_episode(out, log.scenario, log.seed, **kwargs)
    match = None
    if log.final_ground_truth_sha256 is not None:
        match = ground_truth_digest(summary.final_ground_truth) == log.final_ground_truth_sha256
    if summary.steps != len(log.actions):
        match = False
    return summary, match
