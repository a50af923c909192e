"""Episode logs: the JSON files that let ``crossing-replay episode`` re-run a seeded episode bit-exactly.

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

import dataclasses
import hashlib
import json
import os
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crossing_common.files import write_text_atomic
from crossing_env.types import GroundTruth
from crossing_replay.errors import LOG_HEADS, ReplayError, check_output
from scenarios import dump_scenario, load_scenario, parse_scenario
from scenarios.config import EnvConfig, ScenarioConfig

EPISODE_LOG_FORMAT = "crossing-env-episode-log"
EPISODE_LOG_VERSION = 1


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
                array = np.asarray(value[key])
                # An object array's bytes are pointers (they differ between runs); hash its text instead.
                data = repr(value[key]).encode() if array.dtype == object else array.tobytes()
                h.update(data)
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
        scenario = load_scenario(scenario)
    if isinstance(scenario, ScenarioConfig):
        return {"toml": dump_scenario(scenario)}
    return str(scenario)


def _scenario_from_data(sc: Any, p: Path) -> str | ScenarioConfig:
    """Inverse of `_scenario_to_data`; `p` (the log file) is named in errors."""
    if isinstance(sc, str) and sc:
        return sc
    if isinstance(sc, dict) and isinstance(sc.get("toml"), str):
        return parse_scenario(sc["toml"], source=f"{p} (field 'scenario.toml')")
    raise ReplayError(f"{p}: field 'scenario' = {sc!r}; expected a name/path or {{'toml': '<text>'}}")


def _actions_from_data(raw: Any, p: Path) -> np.ndarray:
    """(T, 1) float32 actions from the log's ``actions`` rows, each a finite number in [−1, 1]."""
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
    return actions


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
    check_output(out, LOG_HEADS, "an episode log")
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
    scenario = _scenario_from_data(data["scenario"], p)
    actions = _actions_from_data(data["actions"], p)
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
