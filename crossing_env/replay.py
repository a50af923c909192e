"""`crossing-replay`: write crossing episodes and real pedestrian scenes to rerun recordings (`.rrd`).

Subcommands:

* ``record --scenario NAME --policy NAME --seed N --out episode.rrd [--steps N] [--predictor M]
  [--intention qlb|classical] [--save-log LOG.json] [--view]`` runs one episode of
  ``crossing_env/Crossing-v0`` and logs it. Policies come from ``agents.make_policy`` when it knows the
  name, else the built-ins ``constant`` and ``random``; a policy that reads predictions gets the best
  available predictor wrappers unless ``--predictor`` / ``--intention`` say otherwise;
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

Entities of an episode recording (world coordinates in metres; the 2D view draws +y downwards, like
highway-env's renderer):

* static ``/world/road/{surface,sidewalks,kerbs,markings,stop_lines}`` and ``/world/crossing/stripes``;
* per frame ``/world/ego`` and ``/world/vehicles`` (oriented boxes as closed `LineStrips2D`: `Boxes2D` has no
  rotation), ``/world/pedestrians`` (`Points2D`, id labels, colours by `PedState`), ``/world/signal``,
  ``/world/predictions`` when the observation holds ``predicted_paths``;
* time series ``/metrics/{ego_speed,ego_acceleration,min_distance,ttc}`` and
  ``/intention/ped_<id>`` when the observation holds ``crossing_intention``;
* ``/events/collisions`` and ``/events/behaviour`` (`TextLog`).

Frame ``i`` is logged at ``step = i`` and ``sim_time = i·dt`` seconds; frame 0 is the state after ``reset``,
so an episode of ``n`` steps has ``n + 1`` rows per per-frame entity.

Episode log (JSON, `EPISODE_LOG_FORMAT` version 1) — enough to re-run a seeded episode bit-exactly::

    {
      "format": "crossing-env-episode-log", "version": 1,
      "scenario": "busy_zebra",              # built-in name or path, or {"toml": "<scenario file text>"}
      "seed": 3,                              # the reset seed
      "policy": "random",                     # informative: the actions below are what is replayed
      "predictor": null,                      # trajectory predictor wrapper used when recording, if any
      "intention": null,                      # crossing-intention wrapper used ("qlb", "classical"), if any
      "env_config": null,                     # null = default EnvConfig, else its fields as nested dicts
      "actions": [[0.25], [-1.0], ...],       # one action per step, as given to env.step
      "final_ground_truth_sha256": "…",       # optional: digest of the last GroundTruth, checked on replay
      "metadata": {...}                       # optional, free-form (e.g. the episode's metrics)
    }

Replaying re-runs the seeded episode with those actions. The world draws only from the env's seeded
generator, so the replay is bit-exact; the digest detects a replay made with a different code version.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import importlib
import inspect
import json
import os
import shutil
import subprocess
import sys
import tempfile
import typing
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crossing_env.config import EnvConfig, ScenarioConfig
from crossing_env.files import give_default_permissions, write_text_atomic
from crossing_env.types import GroundTruth, PedState

APP_ID = "crossing_env"
EPISODE_LOG_FORMAT = "crossing-env-episode-log"
EPISODE_LOG_VERSION = 1
BUILTIN_POLICIES: tuple[str, ...] = ("constant", "random")
DATASETS: tuple[str, ...] = ("eth", "hotel", "univ", "zara1", "zara2", "sdd")
SCENE_DT = 0.4
"""Seconds between consecutive distinct frames of the ETH/UCY and SDD files (2.5 Hz)."""

PED_COLOURS: dict[int, tuple[int, int, int]] = {
    PedState.INACTIVE: (128, 128, 128),
    PedState.APPROACHING: (90, 170, 255),
    PedState.WAITING: (255, 200, 0),
    PedState.CROSSING: (255, 70, 50),
    PedState.LEAVING: (90, 210, 100),
}
"""Pedestrian colour per `PedState`: blue approaching, amber waiting, red crossing, green leaving."""
EGO_COLOUR = (0, 230, 255)
VEHICLE_COLOUR = (235, 235, 235)
PREDICTION_COLOUR = (230, 70, 230)
GROUND_TRUTH_COLOUR = (60, 220, 90)
HISTORY_COLOUR = (170, 170, 170)


class ReplayError(ValueError):
    """Bad input to the replay tools (file, field and value named in the message)."""


# ---------------------------------------------------------------------------------------------------------
# Episode logs
# ---------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EpisodeLog:
    """A saved episode: everything needed to re-run it bit-exactly (see the module docstring)."""

    scenario: str | ScenarioConfig
    """Built-in scenario name or path, or an inline scenario config."""
    seed: int
    """Seed passed to `reset`."""
    actions: np.ndarray
    """(T, 1) float32 actions, one per step."""
    policy: str = "unknown"
    """Name of the policy that chose the actions (informative only)."""
    predictor: str | None = None
    """Trajectory predictor wrapped around the env when recording (changes only the observation)."""
    intention: str | None = None
    """Crossing-intention wrapper used when recording (``qlb`` or ``classical``; observation only)."""
    env_config: EnvConfig | None = None
    """Env settings; None means the default `EnvConfig`."""
    final_ground_truth_sha256: str | None = None
    """Digest of the last ground truth (`ground_truth_digest`), checked on replay when present."""
    metadata: dict[str, Any] = field(default_factory=dict)
    """Free-form JSON data (e.g. the episode's metrics)."""


def ground_truth_digest(gt: GroundTruth) -> str:
    """SHA-256 over every numeric field of a ground truth snapshot: equal digests mean identical states."""
    h = hashlib.sha256()
    for name in gt.__dataclass_fields__:
        value = getattr(gt, name)
        if isinstance(value, np.ndarray):
            h.update(name.encode())
            h.update(str(value.dtype).encode())
            h.update(np.ascontiguousarray(value).tobytes())
        elif name == "extras":
            for key in sorted(value):
                h.update(key.encode())
                h.update(np.ascontiguousarray(np.asarray(value[key])).tobytes())
        else:
            h.update(f"{name}={value!r}".encode())
    return h.hexdigest()


def _dataclass_to_data(obj: Any) -> Any:
    """Frozen config dataclass → JSON-ready nested dicts (tuples become lists)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _dataclass_to_data(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (tuple, list)):
        return [_dataclass_to_data(v) for v in obj]
    return obj


def _dataclass_from_data(cls: type, data: Any, where: str) -> Any:
    """Inverse of `_dataclass_to_data` for `EnvConfig`-like trees; unknown fields are errors."""
    if not isinstance(data, Mapping):
        raise ReplayError(f"{where}: expected an object, got {data!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ReplayError(f"{where}: unknown field(s) {unknown}; allowed: {sorted(names)}")
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        tp = hints[key]
        if dataclasses.is_dataclass(tp):
            kwargs[key] = _dataclass_from_data(tp, value, f"{where}.{key}")
        elif typing.get_origin(tp) is tuple:
            kwargs[key] = tuple(value)
        else:
            kwargs[key] = value
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        raise ReplayError(f"{where}: {exc}") from exc


def _scenario_to_data(scenario: str | os.PathLike[str] | ScenarioConfig) -> str | dict[str, str]:
    """Built-in names stay names; configs and scenario files are stored inline (self-contained logs)."""
    if (
        not isinstance(scenario, ScenarioConfig)
        and Path(scenario).suffix == ".toml"
        and Path(scenario).is_file()
    ):
        from scenarios import load_scenario

        scenario = load_scenario(scenario)
    if isinstance(scenario, ScenarioConfig):
        from scenarios import dump_scenario

        return {"toml": dump_scenario(scenario)}
    return str(scenario)


def save_episode_log(
    path: str | os.PathLike[str],
    *,
    scenario: str | os.PathLike[str] | ScenarioConfig,
    seed: int,
    actions: Sequence[Any] | np.ndarray,
    policy: str = "unknown",
    predictor: str | None = None,
    env_config: EnvConfig | None = None,
    final_ground_truth: GroundTruth | None = None,
    intention: str | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Write an episode log (JSON, atomically) that `crossing-replay episode` re-runs.

    Args:
        path: Output file (``.json``).
        scenario: Built-in name (stored as the name), or scenario file path or config (stored inline as TOML
            text, so the log does not depend on the file).
        seed: The seed given to ``env.reset``.
        actions: The actions given to ``env.step``, in order (each a number or a length-1 array).
        policy: Name of the policy, for the reader.
        predictor: Trajectory-predictor observation wrapper used, if any (e.g. ``"cvm"``).
        intention: Crossing-intention wrapper used, if any (``"qlb"`` or ``"classical"``).
        env_config: Non-default env settings, if any.
        final_ground_truth: Last ground truth of the episode; its digest lets the replay check itself.
        metadata: Extra JSON-serialisable data (e.g. metrics), stored under ``"metadata"``.

    Returns:
        The path written.
    """
    acts = (
        np.asarray(actions, dtype=np.float32).reshape(len(actions), -1) if len(actions) else np.zeros((0, 1))
    )
    if acts.shape[1] != 1 or not np.isfinite(acts).all():
        raise ReplayError(f"save_episode_log({path}): actions must be finite numbers, one per step")
    data = {
        "format": EPISODE_LOG_FORMAT,
        "version": EPISODE_LOG_VERSION,
        "scenario": _scenario_to_data(scenario),
        "seed": int(seed),
        "policy": str(policy),
        "predictor": predictor,
        "intention": None if intention in (None, "none") else intention,
        "env_config": None
        if env_config is None or env_config == EnvConfig()
        else _dataclass_to_data(env_config),
        # float32 → Python float is exact, and so is the way back: the replay feeds identical actions.
        "actions": [[float(a) for a in row] for row in acts],
        "final_ground_truth_sha256": None
        if final_ground_truth is None
        else ground_truth_digest(final_ground_truth),
        "metadata": dict(metadata or {}),
    }
    out = Path(path)
    try:
        text = json.dumps(data, indent=1, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ReplayError(f"save_episode_log({out}): metadata is not JSON-serialisable ({exc})") from exc
    write_text_atomic(out, text + "\n")
    return out


def load_episode_log(path: str | os.PathLike[str]) -> EpisodeLog:
    """Read and validate an episode log; errors name the file, the field and the value."""
    p = Path(path)
    if not p.is_file():
        raise ReplayError(f"episode log not found: {p}")
    try:
        data = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ReplayError(f"{p}: not valid JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise ReplayError(f"{p}: top level must be an object, got {type(data).__name__}")
    if data.get("format") != EPISODE_LOG_FORMAT:
        raise ReplayError(f"{p}: field 'format' = {data.get('format')!r}; expected {EPISODE_LOG_FORMAT!r}")
    if data.get("version") != EPISODE_LOG_VERSION:
        raise ReplayError(f"{p}: field 'version' = {data.get('version')!r}; supported: {EPISODE_LOG_VERSION}")
    for key in ("scenario", "seed", "actions"):
        if key not in data:
            raise ReplayError(f"{p}: missing field {key!r}")
    seed = data["seed"]
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise ReplayError(f"{p}: field 'seed' = {seed!r}; expected a non-negative integer")
    sc = data["scenario"]
    scenario: str | ScenarioConfig
    if isinstance(sc, str) and sc:
        scenario = sc
    elif isinstance(sc, dict) and isinstance(sc.get("toml"), str):
        from scenarios import parse_scenario

        scenario = parse_scenario(sc["toml"], source=f"{p} (field 'scenario.toml')")
    else:
        raise ReplayError(f"{p}: field 'scenario' = {sc!r}; expected a name/path or {{'toml': '<text>'}}")
    raw = data["actions"]
    try:
        actions = (
            np.asarray(raw, dtype=np.float32).reshape(len(raw), -1) if raw else np.zeros((0, 1), np.float32)
        )
    except (TypeError, ValueError) as exc:
        raise ReplayError(f"{p}: field 'actions' must be a list of [number] rows ({exc})") from exc
    if actions.shape[1] != 1:
        raise ReplayError(f"{p}: field 'actions' rows have {actions.shape[1]} numbers; expected 1")
    bad = np.flatnonzero(~np.isfinite(actions[:, 0]) | (np.abs(actions[:, 0]) > 1.0))
    if bad.size:
        i = int(bad[0])
        raise ReplayError(f"{p}: field 'actions[{i}]' = {raw[i]!r}; expected a finite number in [-1, 1]")
    env_cfg = data.get("env_config")
    env_config = (
        None if env_cfg is None else _dataclass_from_data(EnvConfig, env_cfg, f"{p}: field 'env_config'")
    )
    digest = data.get("final_ground_truth_sha256")
    if digest is not None and not isinstance(digest, str):
        raise ReplayError(f"{p}: field 'final_ground_truth_sha256' = {digest!r}; expected a hex string")
    predictor, intention = data.get("predictor"), data.get("intention")
    for key, value in (("predictor", predictor), ("intention", intention)):
        if value is not None and not isinstance(value, str):
            raise ReplayError(f"{p}: field {key!r} = {value!r}; expected a string or null")
    predictor = None if predictor == "none" else predictor
    intention = None if intention == "none" else intention
    return EpisodeLog(
        scenario=scenario,
        seed=seed,
        actions=actions,
        policy=str(data.get("policy", "unknown")),
        predictor=predictor,
        intention=intention,
        env_config=env_config,
        final_ground_truth_sha256=digest,
        metadata=dict(data.get("metadata") or {}),
    )


# ---------------------------------------------------------------------------------------------------------
# Policies and episodes
# ---------------------------------------------------------------------------------------------------------

Policy = Callable[[dict[str, np.ndarray]], np.ndarray]


def _builtin_policy(name: str, seed: int) -> Policy:
    if name == "constant":
        return lambda obs: np.zeros(1, dtype=np.float32)
    rng = np.random.default_rng(seed)
    return lambda obs: rng.uniform(-1.0, 1.0, size=1).astype(np.float32)


def _adapt_policy(obj: Any, seed: int) -> Policy:
    """Wrap whatever `agents.make_policy` returned into ``obs -> action``."""
    reset = getattr(obj, "reset", None)
    if callable(reset):
        try:
            reset(seed=seed)
        except TypeError:
            reset()
    if callable(getattr(obj, "act", None)):
        return lambda obs: np.asarray(obj.act(obs), dtype=np.float32).reshape(1)
    if callable(getattr(obj, "predict", None)):  # Stable-Baselines3 models
        return lambda obs: np.asarray(obj.predict(obs, deterministic=True)[0], dtype=np.float32).reshape(1)
    if callable(obj):
        return lambda obs: np.asarray(obj(obs), dtype=np.float32).reshape(1)
    raise ReplayError(f"policy object {obj!r} has no act(), predict() or __call__")


def make_policy(name: str, seed: int, env: Any = None) -> Policy:
    """A policy by name: through ``agents.make_policy`` when it exists, else the built-ins.

    The built-ins are ``constant`` (action 0: hold speed) and ``random`` (uniform in [−1, 1] from a
    generator seeded with `seed`). ``agents`` is imported lazily so recordings work without it.
    """
    maker = None
    try:
        agents = importlib.import_module("agents")
        maker = getattr(agents, "make_policy", None)
    except ImportError:
        agents = None
    if maker is not None:
        offer: dict[str, Any] = {"env": env, "seed": seed, "rng": np.random.default_rng(seed)}
        if env is not None:
            offer["scenario"] = env.unwrapped.scenario
            offer["dt"] = env.unwrapped.config.dt
        params = inspect.signature(maker).parameters
        named = {k for k, p in params.items() if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
        kwargs = {k: v for k, v in offer.items() if k in named}
        try:
            return _adapt_policy(maker(name, **kwargs), seed)
        except (KeyError, LookupError, ValueError) as exc:
            if name not in BUILTIN_POLICIES:
                raise ReplayError(f"--policy {name!r}: {exc}") from exc
    if name in BUILTIN_POLICIES:
        return _builtin_policy(name, seed)
    raise ReplayError(
        f"--policy {name!r} is unknown; built-in policies: {', '.join(BUILTIN_POLICIES)}"
        + ("" if maker else " (agents.make_policy not available)")
    )


INTENTION_WRAPPERS: dict[str, str] = {"qlb": "QLBIntention", "classical": "ClassicalIntention"}
"""``--intention`` names → wrappers in ``predictors.intention`` that add ``crossing_intention``."""


def make_env(
    scenario: str | os.PathLike[str] | ScenarioConfig,
    predictor: str | None = None,
    config: EnvConfig | None = None,
    intention: str | None = None,
) -> Any:
    """``gym.make("crossing_env/Crossing-v0", ...)`` with the requested predictor wrappers.

    The intention wrapper goes on first and the trajectory predictor second, as in ``crossing-eval``, so
    a policy sees the same observations as in the evaluation.
    """
    import gymnasium as gym

    import crossing_env  # registers the env

    kwargs: dict[str, Any] = {"scenario": scenario}
    if config is not None:
        kwargs["config"] = config
    env = gym.make(crossing_env.ENV_ID, **kwargs)
    try:
        if intention:
            if intention not in INTENTION_WRAPPERS:
                raise ReplayError(f"--intention {intention!r}: allowed {', '.join(INTENTION_WRAPPERS)}")
            try:
                module = importlib.import_module("predictors.intention")
            except ImportError as exc:
                raise ReplayError(
                    f"--intention {intention!r}: predictors.intention unavailable ({exc})"
                ) from exc
            cls = getattr(module, INTENTION_WRAPPERS[intention], None)
            if cls is None:
                raise ReplayError(
                    f"--intention {intention!r}: predictors.intention has no {INTENTION_WRAPPERS[intention]}"
                )
            env = cls(env)
        if predictor:
            try:
                from predictors.trajectory_wrapper import TrajectoryPrediction
            except ImportError as exc:
                raise ReplayError(f"--predictor {predictor!r}: predictors unavailable ({exc})") from exc
            try:
                env = TrajectoryPrediction(env, model=predictor)
            except (OSError, ValueError, RuntimeError) as exc:
                raise ReplayError(f"--predictor {predictor!r}: {exc}") from exc
    except BaseException:
        env.close()
        raise
    return env


def _policy_uses_predictors(name: str) -> bool:
    """Whether an ``agents`` policy reads ``predicted_paths`` / ``crossing_intention`` (False if unknown)."""
    try:
        from agents.policies import policy_uses_predictors
    except ImportError:
        return False
    try:
        return bool(policy_uses_predictors(name))
    except (KeyError, ValueError):
        return False


def _auto_env(
    scenario: str | os.PathLike[str] | ScenarioConfig, config: EnvConfig | None
) -> tuple[Any, str | None, str | None]:
    """Env for a predictor-using policy when no wrapper was asked for: the best available combination."""
    notes = []
    for predictor, intention in (
        ("s-cgru", "qlb"),
        ("cvm", "qlb"),
        ("s-cgru", None),
        ("cvm", None),
        (None, None),
    ):
        try:
            env = make_env(scenario, predictor, config, intention)
        except ReplayError as exc:
            notes.append(str(exc))
            continue
        print(
            f"crossing-replay: the policy uses predictors: predictor={predictor}, intention={intention}"
            + (f" (skipped: {'; '.join(notes)})" if notes else ""),
            file=sys.stderr,
        )
        return env, predictor, intention
    raise AssertionError("unreachable: the bare env always builds")


@dataclass
class Frame:
    """One logged frame of an episode."""

    step: int
    """Frame index (0 = after reset)."""
    observation: dict[str, np.ndarray]
    """The observation the policy saw."""
    ground_truth: GroundTruth
    """The world's true state."""
    slot_ids: np.ndarray
    """(K,) pedestrian id shown in each observation slot (−1 = empty), for predictions and intentions."""
    action: np.ndarray | None
    """Action that produced this frame (None for frame 0)."""


def _slot_ids(env: Any) -> np.ndarray:
    base = env.unwrapped
    observer = getattr(base, "_observer", None)
    slots = getattr(observer, "last_slots", None)
    if slots is None or base.world is None:
        return np.zeros(0, dtype=np.int64)
    ids = base.world.pedestrians.ids
    return np.where(slots >= 0, ids[np.maximum(slots, 0)], -1).astype(np.int64)


def run_episode(
    env: Any,
    seed: int,
    policy: Policy | None = None,
    actions: np.ndarray | None = None,
    max_steps: int | None = None,
) -> Iterator[Frame]:
    """Reset with `seed` and step with `policy` (or the given `actions`), yielding every frame.

    Stops at termination, truncation, `max_steps`, or the end of `actions`.
    """
    if (policy is None) == (actions is None):
        raise ValueError("run_episode needs exactly one of policy and actions")
    obs, info = env.reset(seed=seed)
    yield Frame(0, obs, info["ground_truth"], _slot_ids(env), None)
    limit = len(actions) if actions is not None else (max_steps if max_steps is not None else sys.maxsize)
    if max_steps is not None:
        limit = min(limit, max_steps)
    step = 0
    while step < limit:
        action = actions[step] if actions is not None else policy(obs)  # type: ignore[misc]
        action = np.asarray(action, dtype=np.float32).reshape(1)
        obs, _, terminated, truncated, info = env.step(action)
        step += 1
        yield Frame(step, obs, info["ground_truth"], _slot_ids(env), action)
        if terminated or truncated:
            break


# ---------------------------------------------------------------------------------------------------------
# Recording
# ---------------------------------------------------------------------------------------------------------


@contextmanager
def open_recording(out: str | os.PathLike[str], recording_id: str, blueprint: Any = None) -> Iterator[Any]:
    """A `rerun.RecordingStream` writing to a temporary file that replaces `out` only on success."""
    import rerun as rr

    path = Path(out)
    if path.suffix != ".rrd":
        raise ReplayError(f"--out {str(path)!r}: the output must end in .rrd")
    if not path.parent.is_dir():
        raise ReplayError(f"--out {str(path)!r}: folder {str(path.parent)!r} does not exist")
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


def box_corners(centres: np.ndarray, sizes: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """(N, 5, 2) closed outlines of oriented boxes: centre (N, 2), (length, width) (N, 2), heading (N,)."""
    half = sizes[:, None, :] / 2 * np.array([[1, 1], [1, -1], [-1, -1], [-1, 1], [1, 1]], dtype=np.float64)
    c, s = np.cos(headings)[:, None], np.sin(headings)[:, None]
    x = half[..., 0] * c - half[..., 1] * s
    y = half[..., 0] * s + half[..., 1] * c
    return np.stack([x, y], axis=-1) + centres[:, None, :]


def _dashes(x0: float, x1: float, y: float, dash: float = 3.0, gap: float = 6.0) -> np.ndarray:
    starts = np.arange(x0, x1 - dash, dash + gap)
    return np.stack(
        [
            np.stack([starts, np.full_like(starts, y)], 1),
            np.stack([starts + dash, np.full_like(starts, y)], 1),
        ],
        axis=1,
    )


def episode_blueprint(scenario: ScenarioConfig, intention: bool = False) -> Any:
    """Viewer layout: the road around the crossing on top, metrics and events below.

    The side panels start collapsed so the road gets the room; the intention plot appears only when the
    observation holds ``crossing_intention``.
    """
    import rerun.blueprint as rrb

    road = scenario.road
    x = scenario.crossing.position
    margin = road.sidewalk_width + 1.0
    plots: list[Any] = [rrb.TimeSeriesView(origin="/metrics", name="safety")]
    if intention:
        plots.append(rrb.TimeSeriesView(origin="/intention", name="crossing intention"))
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


class EpisodeRecorder:
    """Logs the static road and each `Frame` of an episode to a rerun recording stream."""

    def __init__(self, rec: Any, scenario: ScenarioConfig, dt: float) -> None:
        self.rec = rec
        self.scenario = scenario
        self.dt = dt
        self.intention_ids: set[int] = set()
        try:
            from crossing_env import metrics
        except ImportError:  # metrics are optional: fall back to centre distances and no TTC
            metrics = None  # type: ignore[assignment]
        self.metrics = metrics

    def log_static(self) -> None:
        """Road surface, sidewalks, kerbs, lane markings, stop lines and the crossing's stripes."""
        import rerun as rr

        from crossing_env.road import RoadGeometry

        sc = self.scenario
        geo = RoadGeometry(sc.road, sc.crossing)
        road, length, w = sc.road, sc.road.length, sc.road.road_width
        log = self.rec.log
        log(
            "world/road/surface",
            rr.LineStrips2D(
                [[[0.0, w / 2], [length, w / 2]]], radii=w / 2, colors=(70, 70, 75), draw_order=0.0
            ),
            static=True,
        )
        sw = road.sidewalk_width
        walks = [[[0.0, -sw / 2], [length, -sw / 2]], [[0.0, w + sw / 2], [length, w + sw / 2]]]
        log(
            "world/road/sidewalks",
            rr.LineStrips2D(
                walks,
                radii=sw / 2,
                colors=(125, 120, 110),
                draw_order=1.0,
            ),
            static=True,
        )
        log(
            "world/road/kerbs",
            rr.LineStrips2D(
                [
                    [[0.0, geo.kerb_south], [length, geo.kerb_south]],
                    [[0.0, geo.kerb_north], [length, geo.kerb_north]],
                ],
                radii=0.12,
                colors=(210, 210, 200),
                draw_order=2.0,
            ),
            static=True,
        )
        n_fwd, lw = road.num_forward_lanes, road.lane_width
        strips: list[np.ndarray] = []
        colours: list[tuple[int, int, int]] = []
        for i in range(1, road.num_lanes):
            y = i * lw
            if i == n_fwd and 0 < n_fwd < road.num_lanes:  # centre line between the two directions
                strips.append(np.array([[0.0, y], [length, y]]))
                colours.append((240, 200, 0))
            else:
                for d in _dashes(0.0, length, y):
                    strips.append(d)
                    colours.append((230, 230, 230))
        if strips:
            log(
                "world/road/markings",
                rr.LineStrips2D(strips, radii=0.08, colors=colours, draw_order=2.0),
                static=True,
            )
        if geo.has_crossing:
            rect = geo.crossing_rect
            ys = np.arange(rect.y_min + 0.5, rect.y_max - 0.25, 1.0)
            stripes = [[[rect.x_min, y], [rect.x_max, y]] for y in ys]
            log(
                "world/crossing/stripes",
                rr.LineStrips2D(stripes, radii=0.25, colors=(245, 245, 245), draw_order=3.0),
                static=True,
            )
            stops = []
            for lane in range(road.num_lanes):
                direction = geo.lane_direction[lane]
                x = geo.stop_line_x(direction)
                lo, hi = geo.lane_bounds(lane)
                stops.append([[x, lo + 0.1], [x, hi - 0.1]])
            log(
                "world/road/stop_lines",
                rr.LineStrips2D(stops, radii=0.15, colors=(245, 245, 245), draw_order=3.0),
                static=True,
            )
        # Text logs are shown only on a timeline (a static entry is hidden): log this one at frame 0.
        self.rec.set_time("step", sequence=0)
        self.rec.set_time("sim_time", duration=0.0)
        log("events/info", rr.TextLog(f"scenario {sc.name}: {sc.description}", level="INFO"))

    def _safety(self, gt: GroundTruth) -> tuple[float, float]:
        """(minimum ego–pedestrian separation, minimum ego–pedestrian TTC); inf without pedestrians."""
        if gt.pedestrian_ids.size == 0:
            return np.inf, np.inf
        length, width = gt.ego_size
        if self.metrics is None:
            d = np.hypot(*(gt.pedestrian_positions - gt.ego_position).T) - gt.pedestrian_radii
            return float(d.min()), np.inf
        sep = self.metrics.box_circle_separation(
            gt.ego_position, length, width, gt.pedestrian_positions, gt.pedestrian_radii
        )
        ttc = self.metrics.box_circle_ttc(
            gt.ego_position,
            gt.ego_velocity,
            length,
            width,
            gt.pedestrian_positions,
            gt.pedestrian_velocities,
            gt.pedestrian_radii,
        )
        return float(np.min(sep)), float(np.min(ttc))

    def log_frame(self, frame: Frame) -> None:
        """Log one frame at ``step = frame.step`` and ``sim_time = gt.time``."""
        import rerun as rr

        rec, gt = self.rec, frame.ground_truth
        rec.set_time("step", sequence=frame.step)
        rec.set_time("sim_time", duration=float(gt.time))
        ego = box_corners(gt.ego_position[None], np.asarray([gt.ego_size]), np.zeros(1))
        rec.log(
            "world/ego", rr.LineStrips2D(ego, radii=0.12, colors=EGO_COLOUR, labels=["ego"], draw_order=10.0)
        )
        heading = np.where(gt.vehicle_velocities[:, 0] < 0, np.pi, 0.0)
        cars = box_corners(gt.vehicle_positions, gt.vehicle_sizes, heading)
        rec.log(
            "world/vehicles",
            rr.LineStrips2D(
                cars,
                radii=0.08,
                colors=VEHICLE_COLOUR,
                labels=[f"car {i}" for i in gt.vehicle_ids],
                draw_order=9.0,
            ),
        )
        colours = np.array(
            [PED_COLOURS.get(int(s), (128, 128, 128)) for s in gt.pedestrian_states], dtype=np.uint8
        ).reshape(-1, 3)
        rec.log(
            "world/pedestrians",
            rr.Points2D(
                gt.pedestrian_positions,
                radii=gt.pedestrian_radii,
                colors=colours,
                labels=[str(i) for i in gt.pedestrian_ids],
                class_ids=gt.pedestrian_states.astype(np.uint16),
                draw_order=12.0,
            ),
        )
        if gt.signal_pedestrian_green is not None:
            x = self.scenario.crossing.position
            colour = (60, 230, 60) if gt.signal_pedestrian_green else (240, 40, 40)
            rec.log(
                "world/signal",
                rr.Points2D(
                    [[x, -0.6], [x, self.scenario.road.road_width + 0.6]],
                    radii=0.45,
                    colors=colour,
                    draw_order=11.0,
                ),
            )
        self._log_predictions(frame)
        speed = float(np.hypot(*gt.ego_velocity))
        rec.log("metrics/ego_speed", rr.Scalars(speed))
        rec.log("metrics/ego_acceleration", rr.Scalars(gt.ego_acceleration))
        dist, ttc = self._safety(gt)
        if np.isfinite(dist):
            rec.log("metrics/min_distance", rr.Scalars(dist))
        if np.isfinite(ttc):
            rec.log("metrics/ttc", rr.Scalars(ttc))
        for c in gt.collisions:
            rec.log(
                "events/collisions",
                rr.TextLog(
                    f"t={c.time:.1f}s collision with {c.kind} {c.other_id} at {c.relative_speed:.1f} m/s "
                    f"({'compliant' if c.compliant else 'non-compliant'} road user)",
                    level="ERROR",
                ),
            )
        for e in gt.events:
            level = "WARN" if e.kind in ("jaywalk", "red_light", "run", "distracted") else "INFO"
            rec.log(
                "events/behaviour",
                rr.TextLog(f"t={e.time:.1f}s pedestrian {e.pedestrian_id}: {e.kind}", level=level),
            )

    def _log_predictions(self, frame: Frame) -> None:
        import rerun as rr

        obs, ids, gt = frame.observation, frame.slot_ids, frame.ground_truth
        paths = obs.get("predicted_paths")
        if paths is not None and ids.size:
            present = np.flatnonzero(ids[: paths.shape[0]] >= 0)
            strips = paths[present].astype(np.float64) + gt.ego_position  # ego frame → world
            rec_ids = ids[present]
            rows = {int(i): k for k, i in enumerate(gt.pedestrian_ids)}
            starts = np.array(
                [
                    gt.pedestrian_positions[rows[int(i)]] if int(i) in rows else s[0]
                    for i, s in zip(rec_ids, strips, strict=True)
                ]
            ).reshape(-1, 2)
            full = np.concatenate([starts[:, None], strips], axis=1) if len(strips) else strips
            self.rec.log(
                "world/predictions",
                rr.LineStrips2D(
                    full,
                    radii=0.06,
                    colors=PREDICTION_COLOUR,
                    labels=[str(i) for i in rec_ids],
                    show_labels=False,
                    draw_order=8.0,
                ),
            )
        intent = obs.get("crossing_intention")
        if intent is not None and ids.size:
            present = np.flatnonzero(ids[: intent.shape[0]] >= 0)
            for k in present:
                pid = int(ids[k])
                self.rec.log(f"intention/ped_{pid}", rr.Scalars(float(intent[k])))
                self.intention_ids.add(pid)


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

    A policy from ``agents`` that reads predictions gets the best available wrappers when neither
    `predictor` nor `intention` is given (S-CGRU, else constant velocity; QLB intention if present).
    """
    if max_steps is not None and max_steps < 1:
        raise ReplayError(f"--steps {max_steps}: must be at least 1")
    if seed < 0:
        raise ReplayError(f"--seed {seed}: must be non-negative")
    if actions is None and predictor is None and intention is None and _policy_uses_predictors(policy):
        env, predictor, intention = _auto_env(scenario, env_config)
    else:
        env = make_env(scenario, predictor, env_config, intention)
    try:
        base = env.unwrapped
        pol = None if actions is not None else make_policy(policy, seed, env)
        name = base.scenario.name
        rid = f"{name}-{policy}-seed{seed}"
        taken: list[np.ndarray] = []
        gts: list[GroundTruth] = []
        collisions = 0
        with open_recording(
            out, rid, episode_blueprint(base.scenario, "crossing_intention" in env.observation_space.spaces)
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
    log_path: str | os.PathLike[str], out: str | os.PathLike[str], keep_ground_truth: bool = False
) -> tuple[RecordSummary, bool | None]:
    """Re-run a saved episode into `out`.

    The logged actions are replayed, so the predictor wrappers only add what is drawn (predicted paths,
    intentions); if they cannot be built here, the episode is replayed without them (with a message).

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
        print(f"crossing-replay: {exc}; replaying without predictor wrappers", file=sys.stderr)
        summary = record_episode(out, log.scenario, log.seed, **kwargs)
    match = None
    if log.final_ground_truth_sha256 is not None:
        match = ground_truth_digest(summary.final_ground_truth) == log.final_ground_truth_sha256
    if summary.steps != len(log.actions):
        match = False
    return summary, match


# ---------------------------------------------------------------------------------------------------------
# Real scenes (ETH/UCY, SDD)
# ---------------------------------------------------------------------------------------------------------


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
    model: str, dataset: str, weights_dir: str | os.PathLike[str] | None = None
) -> tuple[Callable[[Any, Any], Any], str]:
    """``(obs, seq_start_end) -> (N, 12, 2)`` and a label saying which predictor it really is.

    Learned models use ``<weights_dir>/<model>_<dataset>.pt`` (default ``predictors/weights``; the ETH/UCY
    checkpoints are trained without that scene, as in ``predictors.evaluate``); when the
    weights or the predictors package are missing, the constant-velocity model is used and the label says so.
    """
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
            from predictors.evaluate import weights_for
            from predictors.train import WEIGHTS_DIR, load_model

            path = weights_for(model, dataset, Path(weights_dir) if weights_dir is not None else WEIGHTS_DIR)
            if path is not None:
                net = load_model(path)
                net.eval()
                return (lambda o, s: net.predict(o, s)), f"{model} ({path.name})"
            reason = f"no weights {model}_{dataset}.pt"
        except (ImportError, ValueError, FileNotFoundError) as exc:
            reason = f"{model} unavailable: {exc}"

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
    start_frame: int = 0,
    max_frames: int | None = None,
    weights_dir: str | os.PathLike[str] | None = None,
) -> SceneSummary:
    """Replay a real recording with predictions (magenta) against the ground-truth futures (green).

    At every frame, each pedestrian with 8 observed positions (3.2 s) gets a 12-step (4.8 s) prediction.
    Unlike the Social-GAN protocol, pedestrians without a complete future are predicted (and pooled over)
    too, because a viewer wants every pedestrian; ADE/FDE are reported only for complete futures.
    """
    import rerun as rr

    if start_frame < 0:
        raise ReplayError(f"--start-frame {start_frame}: must be non-negative")
    if max_frames is not None and max_frames < 1:
        raise ReplayError(f"--max-frames {max_frames}: must be at least 1")
    root = Path(data_root) if data_root is not None else _default_data_root()
    path = scene_file(root, dataset, file)
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
    predictor, label = _load_predictor(model, dataset, weights_dir)
    sp = predict_scene(positions, present, predictor)
    # Ground-truth future: the contiguous prefix of the next 12 frames in which the pedestrian is present.
    fut_t = sp.frame[:, None] + np.arange(1, 13)[None, :]
    valid = fut_t < t_len
    fut_present = np.zeros(fut_t.shape, bool)
    fut_present[valid] = present[fut_t[valid], np.broadcast_to(sp.ped[:, None], fut_t.shape)[valid]]
    fut_len = np.cumprod(fut_present, axis=1).sum(axis=1)
    fut = positions[np.minimum(fut_t, t_len - 1), sp.ped[:, None]]
    complete = fut_len == 12
    err = np.linalg.norm(sp.predicted - fut, axis=-1)
    ade_all = err.mean(axis=1)
    fde_all = err[:, -1]
    colours = _track_colours(len(peds))
    rid = f"{dataset}-{path.stem}-{start_frame}-{stop}-{model}"
    with open_recording(out, rid, scene_blueprint(positions, present)) as rec:
        rec.send_recording_name(f"{dataset}/{path.name} · predictor {label}")
        rec.set_time("step", sequence=0)  # text logs show only on a timeline, not as static data
        rec.set_time("frame", sequence=int(frames_all[start_frame]))
        rec.set_time("sim_time", duration=0.0)
        rec.log(
            "info",
            rr.TextLog(
                f"{path.name}: frames {start_frame}..{stop - 1}; predictor: {label}; "
                "magenta = predicted, green = ground truth, grey = observed",
                level="INFO",
            ),
        )
        order = np.searchsorted(sp.frame, np.arange(t_len + 1))
        for t in range(t_len):
            rec.set_time("step", sequence=t)
            rec.set_time("frame", sequence=int(frames_all[start_frame + t]))
            rec.set_time("sim_time", duration=t * SCENE_DT)
            here = np.flatnonzero(present[t])
            rec.log(
                "scene/pedestrians",
                rr.Points2D(
                    positions[t, here],
                    radii=0.2,
                    colors=colours[here],
                    labels=[str(int(peds[i])) for i in here],
                ),
            )
            lo, hi = order[t], order[t + 1]
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
            gt_strips = [np.concatenate([cur[k], fut[i, : fut_len[i]]]) for k, i in enumerate(idx)]
            rec.log("scene/ground_truth", rr.LineStrips2D(gt_strips, radii=0.06, colors=GROUND_TRUTH_COLOUR))
            done = idx[complete[idx]]
            if done.size:
                rec.log("metrics/ade", rr.Scalars(float(ade_all[done].mean())))
                rec.log("metrics/fde", rr.Scalars(float(fde_all[done].mean())))
    ade = float(ade_all[complete].mean()) if complete.any() else float("nan")
    fde = float(fde_all[complete].mean()) if complete.any() else float("nan")
    return SceneSummary(Path(out), path, t_len, len(sp.frame), label, ade, fde)


def _track_colours(n: int) -> np.ndarray:
    """Distinct, deterministic colours per track (golden-ratio hues)."""
    import colorsys

    hues = (np.arange(n) * 0.618033988749895) % 1.0
    return np.array(
        [[int(255 * c) for c in colorsys.hsv_to_rgb(h, 0.55, 1.0)] for h in hues], dtype=np.uint8
    ).reshape(-1, 3)


def _default_data_root() -> Path:
    env = os.environ.get("CROSSING_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1].parent / "shared" / "data"


# ---------------------------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------------------------


def viewer_executable() -> str | None:
    """Path of the native viewer shipped in the rerun-sdk wheel (`rerun_cli/rerun`), else `rerun` on PATH."""
    try:
        import rerun_cli

        exe = Path(rerun_cli.__file__).parent / "rerun"
        if exe.is_file():
            return str(exe)
    except ImportError:
        pass
    return shutil.which("rerun")


def open_viewer(path: Path) -> subprocess.Popen[bytes]:
    """Start the viewer on `path` in the background (it needs a display)."""
    exe = viewer_executable()
    if exe is None:
        raise ReplayError("--view: the rerun viewer binary was not found (is rerun-sdk installed?)")
    return subprocess.Popen([exe, str(path)], start_new_session=True)


def _shrink_png(src: Path, max_bytes: int) -> None:
    """Quantise (and if needed downscale) a PNG in place until it is under `max_bytes`."""
    from PIL import Image

    with Image.open(src) as im:
        image = im.convert("RGB")
    scale = 1.0
    while True:
        size = (max(1, int(image.width * scale)), max(1, int(image.height * scale)))
        small = image.resize(size, Image.Resampling.LANCZOS) if scale < 1.0 else image
        small.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(src, optimize=True)
        if src.stat().st_size <= max_bytes or scale < 0.2:
            return
        scale *= 0.8


def screenshot(
    rrd: str | os.PathLike[str],
    out: str | os.PathLike[str],
    time_s: float,
    size: tuple[int, int] = (1600, 900),
    port: int = 9877,
    max_bytes: int = 500_000,
    settle_s: float = 11.0,
) -> Path:
    """Screenshot of the whole viewer showing `rrd` at ``sim_time = time_s``, without a display.

    Runs the viewer headless (needs a Vulkan driver; on a CPU-only Linux box Mesa's lavapipe from
    ``mesa-vulkan-drivers``), drives it through the experimental `rerun.experimental.ViewerClient`, waits
    `settle_s` for the start-up notices to fade, then writes a PNG of at most `max_bytes` (atomically).
    """
    import time

    from rerun.experimental import ViewerClient

    src, dst = Path(rrd).resolve(), Path(out)
    if not src.is_file():
        raise ReplayError(f"recording not found: {src}")
    if dst.suffix != ".png" or not dst.parent.is_dir():
        raise ReplayError(f"--out {str(dst)!r}: must be a .png in an existing folder")
    exe = viewer_executable()
    if exe is None:
        raise ReplayError("the rerun viewer binary was not found (is rerun-sdk installed?)")
    env = dict(os.environ, CI="true", WGPU_BACKEND=os.environ.get("WGPU_BACKEND", "vulkan"))
    cmd = [
        exe,
        "--headless",
        "--hide-welcome-screen",
        "--window-size",
        f"{size[0]}x{size[1]}",
        "--port",
        str(port),
    ]
    viewer = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    fd, tmp = tempfile.mkstemp(prefix=f".{dst.name}.", suffix=".png", dir=dst.resolve().parent)
    os.close(fd)
    os.unlink(tmp)
    try:
        client = None
        for _ in range(150):
            if viewer.poll() is not None:
                raise ReplayError(
                    f"viewer exited with code {viewer.returncode} (port {port} in use? no Vulkan?)"
                )
            try:
                client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
                client.get_state()
                break
            except Exception:  # the server is not up yet
                client = None
                time.sleep(0.2)
        if client is None:
            raise ReplayError(f"could not connect to the viewer on port {port}")
        client.open(str(src))
        time.sleep(settle_s)
        client.set_time("sim_time", duration=float(time_s), play_state="paused")
        time.sleep(1.0)
        client.save_screenshot(tmp)
        for _ in range(100):
            if os.path.exists(tmp) and os.path.getsize(tmp) > 0:
                break
            time.sleep(0.1)
        else:
            raise ReplayError("the viewer wrote no screenshot")
        _shrink_png(Path(tmp), max_bytes)
        give_default_permissions(tmp)
        os.replace(tmp, dst)
    finally:
        viewer.terminate()
        try:
            viewer.wait(timeout=10)
        except subprocess.TimeoutExpired:
            viewer.kill()
        if os.path.exists(tmp):
            os.unlink(tmp)
    return dst


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
    p = argparse.ArgumentParser(
        prog="crossing-replay",
        description="Write crossing episodes and real pedestrian scenes to rerun recordings (.rrd); "
        "--view opens them in the rerun viewer.",
    )
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("record", help="run an episode and record it")
    r.add_argument("--scenario", required=True, help="built-in scenario name or scenario TOML path")
    r.add_argument("--policy", default="constant", help="policy (agents.make_policy, or constant/random)")
    r.add_argument("--seed", type=_non_negative_int, default=0, help="reset seed")
    r.add_argument("--out", required=True, help="output .rrd")
    r.add_argument("--steps", type=_positive_int, default=None, help="stop after this many steps")
    r.add_argument("--predictor", default=None, help="trajectory predictor wrapper (cvm, s-cgru, path)")
    r.add_argument("--intention", default=None, choices=sorted(INTENTION_WRAPPERS), help="intention wrapper")
    r.add_argument("--save-log", default=None, help="also write the episode log (JSON) here")
    r.add_argument("--view", action="store_true", help="open the recording in the rerun viewer")
    e = sub.add_parser("episode", help="replay a saved episode log")
    e.add_argument("log", help="episode log (.json) written by save_episode_log")
    e.add_argument("--out", required=True, help="output .rrd")
    e.add_argument("--view", action="store_true", help="open the recording in the rerun viewer")
    s = sub.add_parser("scene", help="replay a real ETH/UCY or SDD scene with predictions")
    s.add_argument("--dataset", required=True, choices=DATASETS)
    s.add_argument("--file", default=None, help="trajectory file (path or name in the dataset's test folder)")
    s.add_argument("--data", default=None, help="data root (default $CROSSING_DATA or <repo>/../shared/data)")
    s.add_argument("--model", default="s-cgru", help="s-cgru, s-lstm, ... (learned), cvm or kalman")
    s.add_argument(
        "--weights", default=None, help="folder of <model>_<dataset>.pt (default predictors/weights)"
    )
    s.add_argument("--start-frame", type=_non_negative_int, default=0, help="first frame index of the slice")
    s.add_argument("--max-frames", type=_positive_int, default=None, help="number of frames to replay")
    s.add_argument("--out", required=True, help="output .rrd")
    s.add_argument("--view", action="store_true", help="open the recording in the rerun viewer")
    g = sub.add_parser("screenshot", help="PNG of the viewer showing a recording (headless, needs Vulkan)")
    g.add_argument("rrd", help="recording (.rrd)")
    g.add_argument("--out", required=True, help="output .png")
    g.add_argument("--time", type=float, default=0.0, help="sim_time to show, seconds")
    g.add_argument("--port", type=_positive_int, default=9877, help="gRPC port of the headless viewer")
    g.add_argument("--max-kb", type=_positive_int, default=500, help="downscale until the PNG is this small")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `crossing-replay`; returns 0 on success, 2 on bad input, 1 on a replay mismatch."""
    args = build_parser().parse_args(argv)
    status = 0
    try:
        if args.command == "record":
            summary = record_episode(
                args.out,
                args.scenario,
                args.seed,
                policy=args.policy,
                max_steps=args.steps,
                predictor=args.predictor,
                intention=args.intention,
            )
            if args.save_log:
                save_episode_log(
                    args.save_log,
                    scenario=args.scenario,
                    seed=args.seed,
                    actions=summary.actions,
                    policy=args.policy,
                    predictor=summary.predictor,
                    intention=summary.intention,
                    final_ground_truth=summary.final_ground_truth,
                )
            print(f"wrote {summary.out}: {summary.steps} steps, {summary.collisions} collision(s)")
        elif args.command == "episode":
            summary, match = replay_episode_log(args.log, args.out)
            print(f"wrote {summary.out}: {summary.steps} steps, {summary.collisions} collision(s)")
            if match is False:
                print(
                    f"crossing-replay: warning: {args.log}: the replay differs from the log (episode "
                    "length vs field 'actions', or final ground truth vs field 'final_ground_truth_sha256'): "
                    "the code or the scenario changed since it was saved",
                    file=sys.stderr,
                )
                status = 1
        elif args.command == "screenshot":
            shot = screenshot(args.rrd, args.out, args.time, port=args.port, max_bytes=args.max_kb * 1000)
            print(f"wrote {shot} ({shot.stat().st_size // 1000} kB)")
            return 0
        else:
            sc = record_scene(
                args.out,
                args.dataset,
                args.data,
                args.file,
                args.model,
                args.start_frame,
                args.max_frames,
                args.weights,
            )
            print(
                f"wrote {sc.out}: {sc.file.name}, {sc.frames} frames, {sc.predictions} predictions, "
                f"predictor {sc.predictor}, ADE {sc.ade:.3f} m, FDE {sc.fde:.3f} m"
            )
    except (ReplayError, ValueError, FileNotFoundError) as exc:
        print(f"crossing-replay: error: {exc}", file=sys.stderr)
        return 2
    if args.view:
        open_viewer(Path(args.out))
    return status


if __name__ == "__main__":
    sys.exit(main())
