"""Replay of real ETH/UCY and SDD pedestrian recordings with trajectory predictions against the ground truth.

Predictions are magenta, ground-truth futures green and observed histories grey. The learned model's weights
may be missing; the constant-velocity model then stands in, and the recording says so.

The ``predictors`` imports here stay inside the functions: ``predictors.baselines``, ``.data`` and
``.checkpoints`` import torch, which ``import crossing_replay`` (and ``crossing-replay --help``) must not
pay for.
"""

from __future__ import annotations

import colorsys
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crossing_replay.errors import ReplayError
from crossing_replay.recorder import PREDICTION_COLOUR, open_recording

DATASETS: tuple[str, ...] = ("eth", "hotel", "univ", "zara1", "zara2", "sdd")
SCENE_DT = 0.4
"""Seconds between consecutive distinct frames of the ETH/UCY and SDD files (2.5 Hz)."""

GROUND_TRUTH_COLOUR = (60, 220, 90)
HISTORY_COLOUR = (170, 170, 170)


def _default_data_root() -> Path:
    env = os.environ.get("CROSSING_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1].parent / "shared" / "data"


def scene_file(data_root: Path, dataset: str, file: str | None) -> Path:
    """The file to replay: `file` (a path, or a name in the test folder), else the first test file."""
    if dataset not in DATASETS:
        raise ReplayError(f"--dataset {dataset!r}: allowed {', '.join(DATASETS)}")
    folder = data_root / "sdd" / "test" if dataset == "sdd" else data_root / "eth_ucy" / dataset / "test"
    if file is not None:
        p = Path(file)
        for cand in (p, folder / p, folder / f"{p}.txt"):
            if cand.is_file():
                return cand
        raise ReplayError(f"--file {file!r}: not a file, nor in {folder}")
    if not folder.is_dir():
        raise ReplayError(f"data folder {folder} not found (set CROSSING_DATA or --data)")
    files = sorted(folder.glob("*.txt"))
    if not files:
        raise ReplayError(f"no .txt trajectory files in {folder}")
    return files[0]


@dataclass(frozen=True)
class SceneSlice:
    """The tracks of a slice of frames of a trajectory file, as dense arrays."""

    frames: np.ndarray
    """(T,) frame numbers of the file, for the ``frame`` timeline."""
    peds: np.ndarray
    """(P,) pedestrian ids of the tracks in the slice."""
    positions: np.ndarray
    """(T, P, 2) positions (zero where absent)."""
    present: np.ndarray
    """(T, P) whether each pedestrian is in each frame."""


SCENE_MODELS = ("s-cgru", "s-gru", "s-lstm", "lstm")
"""Learned models ``scene --model`` accepts (weights ``<model>_<dataset>.pt``)."""


def populated_start(path: Path) -> int:
    """Index of the first frame with at least half the file's peak number of pedestrians.

    The default start of ``scene``: the viewer opens on the first frame, and ETH's first frames are
    almost empty.
    """
    from predictors.data import read_trajectory_file

    try:
        rows = read_trajectory_file(path)
    except ValueError as exc:
        raise ReplayError(str(exc)) from exc
    _, f_idx = np.unique(rows[:, 0], return_inverse=True)
    counts = np.bincount(f_idx)
    return int(np.argmax(counts >= max(1, int(np.ceil(counts.max() / 2))))) if counts.size else 0


def _read_slice(path: Path, start_frame: int, max_frames: int | None) -> SceneSlice:
    """Frames ``start_frame`` .. ``start_frame + max_frames − 1`` of a trajectory file."""
    from predictors.data import read_trajectory_file

    try:
        rows = read_trajectory_file(path)
    except ValueError as exc:
        raise ReplayError(str(exc)) from exc
    frames_all, f_idx = np.unique(rows[:, 0], return_inverse=True)
    stop = len(frames_all) if max_frames is None else min(len(frames_all), start_frame + max_frames)
    if start_frame >= len(frames_all):
        raise ReplayError(f"--start-frame {start_frame}: {path} has only {len(frames_all)} frames")
    keep = (f_idx >= start_frame) & (f_idx < stop)
    rows, f_idx = rows[keep], f_idx[keep] - start_frame
    peds, p_idx = np.unique(rows[:, 1], return_inverse=True)
    t_len = stop - start_frame
    positions = np.zeros((t_len, len(peds), 2))
    present = np.zeros((t_len, len(peds)), bool)
    positions[f_idx, p_idx] = rows[:, 2:4]
    present[f_idx, p_idx] = True
    return SceneSlice(frames_all[start_frame:stop], peds, positions, present)


@dataclass(frozen=True)
class ScenePredictions:
    """Predictions at every frame of a scene slice for the pedestrians with 8 observed positions."""

    frame: np.ndarray
    """(N,) frame index (into the slice) at which the prediction is made."""
    ped: np.ndarray
    """(N,) track column."""
    observed: np.ndarray
    """(N, 8, 2) observed positions, oldest first."""
    predicted: np.ndarray
    """(N, 12, 2) predicted positions."""


def _load_predictor(
    model: str,
    dataset: str,
    weights_dir: str | os.PathLike[str] | None = None,
    allow_fallback: bool = False,
) -> tuple[Callable[[Any, Any], Any], str]:
    """``(obs, seq_start_end) -> (N, 12, 2)`` and a label saying which predictor it really is.

    Learned models use ``<weights_dir>/<model>_<dataset>.pt`` (default ``predictors/weights``; the ETH/UCY
    checkpoints are trained without that scene; ``predictors.checkpoints.weights_for``). An unknown model
    name is an error; so are missing or unloadable weights, unless `allow_fallback` (``--fallback-cvm``),
    when the constant-velocity model stands in and the label says so.

    Raises:
        ReplayError: unknown model, or a learned model that cannot be loaded without `allow_fallback`.
    """
    known = ("cvm", "kalman", *SCENE_MODELS)
    if model not in known:
        raise ReplayError(f"--model {model!r}: unknown; choose from {', '.join(known)}")
    try:
        from predictors.baselines import cvm
    except ImportError:
        cvm = None
    if model in ("cvm", "kalman") and cvm is not None:
        if model == "kalman":
            from predictors.baselines import kalman_predict

            return (lambda o, s: kalman_predict(o)), "kalman"
        return (lambda o, s: cvm(o)), "cvm"
    reason = "predictors package unavailable"
    if cvm is not None and model != "cvm":
        try:
            from predictors.checkpoints import WEIGHTS_DIR, load_model, weights_for

            path = weights_for(model, dataset, Path(weights_dir) if weights_dir is not None else WEIGHTS_DIR)
            if path is not None:
                net = load_model(path)
                net.eval()
                return (lambda o, s: net.predict(o, s)), f"{model} ({path.name})"
            reason = f"no weights {model}_{dataset}.pt"
        except (ImportError, ValueError, FileNotFoundError) as exc:
            reason = f"{model} unavailable: {exc}"

    if not allow_fallback:
        raise ReplayError(
            f"--model {model!r}: {reason} (give --fallback-cvm to use constant velocity instead)"
        )

    def constant_velocity(obs: Any, sse: Any) -> Any:
        v = obs[:, -1] - obs[:, -2]
        steps = np.arange(1, 13, dtype=np.float32)[None, :, None]
        return obs[:, -1:] + v[:, None] * (steps if isinstance(obs, np.ndarray) else _torch_tensor(steps))

    return constant_velocity, f"constant velocity (fallback: {reason})"


def _torch_tensor(a: np.ndarray) -> Any:
    import torch

    return torch.from_numpy(a)


def predict_scene(
    positions: np.ndarray, present: np.ndarray, predictor: Callable[[Any, Any], Any], batch: int = 4096
) -> ScenePredictions:
    """Predict 12 steps for every (frame, pedestrian) with 8 observed positions, batched over frames.

    All pedestrians predicted at one frame form one window (the social models pool over it).
    """
    import torch

    t_len, n_peds = present.shape
    csum = np.concatenate([np.zeros((1, n_peds), np.int64), np.cumsum(present, axis=0)])
    full = np.zeros_like(present)
    if t_len >= 8:
        full[7:] = (csum[8:] - csum[:-8]) == 8
    frame_idx, ped_idx = np.nonzero(full)
    obs = positions[frame_idx[:, None] + np.arange(-7, 1)[None, :], ped_idx[:, None]].astype(np.float32)
    preds = np.zeros((len(frame_idx), 12, 2), np.float32)
    frames = np.unique(frame_idx)
    with torch.no_grad():
        start = 0
        while start < len(frames):
            # take whole frames until the batch is full
            rows_end = start
            lo = np.searchsorted(frame_idx, frames[start])
            hi = lo
            while rows_end < len(frames):
                nxt = np.searchsorted(frame_idx, frames[rows_end], side="right")
                if nxt - lo > batch and rows_end > start:
                    break
                hi, rows_end = nxt, rows_end + 1
            f = frame_idx[lo:hi]
            _, counts = np.unique(f, return_counts=True)
            ends = np.cumsum(counts)
            sse = torch.as_tensor(np.stack([ends - counts, ends], 1), dtype=torch.int64)
            out = predictor(torch.from_numpy(obs[lo:hi]), sse)
            preds[lo:hi] = np.asarray(out, dtype=np.float32)
            start = rows_end
    return ScenePredictions(frame_idx, ped_idx, obs, preds)


@dataclass(frozen=True)
class _Futures:
    """The true futures of a scene's predictions, and the predictions' errors against them."""

    positions: np.ndarray
    """(N, 12, 2) true positions after each prediction (valid for the first `length` steps)."""
    length: np.ndarray
    """(N,) contiguous prefix of the next 12 frames in which the pedestrian is present."""
    ade: np.ndarray
    """(N,) average displacement error (meaningful where `complete`)."""
    fde: np.ndarray
    """(N,) final displacement error (meaningful where `complete`)."""

    @property
    def complete(self) -> np.ndarray:
        """(N,) whether all 12 true future positions exist."""
        return self.length == 12


def _futures(sp: ScenePredictions, positions: np.ndarray, present: np.ndarray) -> _Futures:
    """Ground-truth future: the contiguous prefix of the next 12 frames in which the pedestrian is present."""
    t_len = present.shape[0]
    fut_t = sp.frame[:, None] + np.arange(1, 13)[None, :]
    valid = fut_t < t_len
    fut_present = np.zeros(fut_t.shape, bool)
    fut_present[valid] = present[fut_t[valid], np.broadcast_to(sp.ped[:, None], fut_t.shape)[valid]]
    fut_len = np.cumprod(fut_present, axis=1).sum(axis=1)
    fut = positions[np.minimum(fut_t, t_len - 1), sp.ped[:, None]]
    err = np.linalg.norm(sp.predicted - fut, axis=-1)
    return _Futures(fut, fut_len, err.mean(axis=1), err[:, -1])


def scene_blueprint(positions: np.ndarray, present: np.ndarray) -> Any:
    """Layout: the scene on top, ADE/FDE below; view bounds fit the tracks."""
    import rerun.blueprint as rrb

    pts = positions[present]
    lo, hi = (pts.min(0) - 2.0, pts.max(0) + 2.0) if len(pts) else (np.zeros(2), np.ones(2))
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Spatial2DView(
                origin="/scene",
                name="scene",
                visual_bounds=rrb.VisualBounds2D(
                    x_range=[float(lo[0]), float(hi[0])], y_range=[float(lo[1]), float(hi[1])]
                ),
            ),
            rrb.Horizontal(
                rrb.TimeSeriesView(origin="/metrics", name="displacement error (m)"),
                rrb.TextLogView(origin="/info", name="info"),
            ),
            row_shares=[3, 1],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline="sim_time", state="collapsed"),
    )


def _track_colours(n: int) -> np.ndarray:
    """Distinct, deterministic colours per track (golden-ratio hues)."""
    hues = (np.arange(n) * 0.618033988749895) % 1.0
    return np.array(
        [[int(255 * c) for c in colorsys.hsv_to_rgb(h, 0.55, 1.0)] for h in hues], dtype=np.uint8
    ).reshape(-1, 3)


def _log_scene_frame(
    rec: Any, t: int, scene: SceneSlice, sp: ScenePredictions, fut: _Futures, colours: np.ndarray
) -> None:
    """Frame `t`: the pedestrians, and the histories, predictions and true futures of those predicted at t."""
    import rerun as rr

    positions, peds = scene.positions, scene.peds
    rec.set_time("step", sequence=t)
    rec.set_time("frame", sequence=int(scene.frames[t]))
    rec.set_time("sim_time", duration=t * SCENE_DT)
    here = np.flatnonzero(scene.present[t])
    rec.log(
        "scene/pedestrians",
        rr.Points2D(
            positions[t, here],
            radii=0.2,
            colors=colours[here],
            labels=[str(int(peds[i])) for i in here],
        ),
    )
    lo, hi = np.searchsorted(sp.frame, [t, t + 1])
    idx = np.arange(lo, hi)
    cur = positions[t, sp.ped[idx]][:, None]
    rec.log("scene/observed", rr.LineStrips2D(sp.observed[idx], radii=0.04, colors=HISTORY_COLOUR))
    rec.log(
        "scene/prediction",
        rr.LineStrips2D(
            np.concatenate([cur, sp.predicted[idx]], 1),
            radii=0.06,
            colors=PREDICTION_COLOUR,
            labels=[str(int(peds[i])) for i in sp.ped[idx]],
            show_labels=False,
        ),
    )
    gt_strips = [np.concatenate([cur[k], fut.positions[i, : fut.length[i]]]) for k, i in enumerate(idx)]
    rec.log("scene/ground_truth", rr.LineStrips2D(gt_strips, radii=0.06, colors=GROUND_TRUTH_COLOUR))
    done = idx[fut.complete[idx]]
    # NaN in frames without a complete prediction, so the series breaks there instead of bridging the gap.
    rec.log("metrics/ade", rr.Scalars(float(fut.ade[done].mean()) if done.size else np.nan))
    rec.log("metrics/fde", rr.Scalars(float(fut.fde[done].mean()) if done.size else np.nan))


@dataclass(frozen=True)
class SceneSummary:
    """What a scene replay produced."""

    out: Path
    """The `.rrd` written."""
    file: Path
    """Trajectory file replayed."""
    frames: int
    """Number of frames logged."""
    predictions: int
    """Number of (frame, pedestrian) predictions drawn."""
    predictor: str
    """Which predictor was really used."""
    ade: float
    """Mean ADE over predictions with a complete 12-step ground truth (nan if none)."""
    fde: float
    """Mean FDE over the same predictions."""


def record_scene(
    out: str | os.PathLike[str],
    dataset: str,
    data_root: str | os.PathLike[str] | None = None,
    file: str | None = None,
    model: str = "s-cgru",
    start_frame: int | None = None,
    max_frames: int | None = None,
    weights_dir: str | os.PathLike[str] | None = None,
    allow_fallback: bool = False,
) -> SceneSummary:
    """Replay a real recording with predictions (magenta) against the ground-truth futures (green).

    At every frame, each pedestrian with 8 observed positions (3.2 s) gets a 12-step (4.8 s) prediction.
    Unlike the Social-GAN protocol, pedestrians without a complete future are predicted (and pooled over)
    too, because a viewer wants every pedestrian; ADE/FDE are reported only for complete futures.
    """
    import rerun as rr

    root = Path(data_root) if data_root is not None else _default_data_root()
    path = scene_file(root, dataset, file)
    if start_frame is None:
        start_frame = populated_start(path)
    if start_frame < 0:
        raise ReplayError(f"--start-frame {start_frame}: must be non-negative")
    if max_frames is not None and max_frames < 1:
        raise ReplayError(f"--max-frames {max_frames}: must be at least 1")
    scene = _read_slice(path, start_frame, max_frames)
    predictor, label = _load_predictor(model, dataset, weights_dir, allow_fallback)
    sp = predict_scene(scene.positions, scene.present, predictor)
    fut = _futures(sp, scene.positions, scene.present)
    colours = _track_colours(len(scene.peds))
    t_len, stop = len(scene.frames), start_frame + len(scene.frames)
    rid = f"{dataset}-{path.stem}-{start_frame}-{stop}-{model}"
    with open_recording(out, rid, scene_blueprint(scene.positions, scene.present)) as rec:
        rec.send_recording_name(f"{dataset}/{path.name} · predictor {label}")
        rec.set_time("step", sequence=0)  # text logs show only on a timeline, not as static data
        rec.set_time("frame", sequence=int(scene.frames[0]))
        rec.set_time("sim_time", duration=0.0)
        rec.log(
            "info",
            rr.TextLog(
                f"{path.name}: frames {start_frame}..{stop - 1}; predictor: {label}; "
                "magenta = predicted, green = ground truth, grey = observed",
                level="INFO",
            ),
        )
        for t in range(t_len):
            _log_scene_frame(rec, t, scene, sp, fut, colours)
    complete = fut.complete
    ade = float(fut.ade[complete].mean()) if complete.any() else float("nan")
    fde = float(fut.fde[complete].mean()) if complete.any() else float("nan")
    return SceneSummary(Path(out), path, t_len, len(sp.frame), label, ade, fde)
