"""Stable-Baselines3 models as driving policies: `SB3Policy("model.zip")(obs) -> action`.

A model trained on `crossing_env/Crossing-v0` (SB3's ``MultiInputPolicy`` on the dict observation) is
loaded with the `VecNormalize` statistics saved beside it, and acts greedily. If the model's observation has
the predictor keys (``crossing_intention``, ``predicted_paths``) the policy asks for the prediction wrappers.
Stable-Baselines3 is the optional ``rl`` extra: ``pip install -e ".[rl]"``.

Model files cannot run code. An SB3 zip holds cloudpickled entries (spaces, schedules, the policy class);
none of them is unpickled: every one is replaced through ``custom_objects`` by a value rebuilt from the
zip's plain JSON (space shapes and dtypes, the policy class chosen by name from SB3's own classes), and the
weights are read with ``torch.load(weights_only=True)`` (SB3's loader). Normalisation statistics are read
only from ``.npz`` data (``np.load(allow_pickle=False)``): ``model.vecnormalize.npz`` or
``vec_normalize.npz`` beside the model (`save_stats` writes them from a `VecNormalize`). A pickled
``*.pkl`` statistics file beside a model is an error, never read and never silently skipped; convert a
trusted one of your own once with `convert_pickled_stats`.
"""

from __future__ import annotations

import json
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from agents.view import ObsLike
from crossing_env.observation import CROSSING_INTENTION_KEY, PREDICTED_PATHS_KEY

PREDICTOR_KEYS = (CROSSING_INTENTION_KEY, PREDICTED_PATHS_KEY)
"""Observation keys that the prediction wrappers add."""
ALGORITHMS = ("PPO", "A2C", "SAC", "TD3", "DDPG")
"""SB3 algorithms whose models load (the one whose policy classes include the zip's is used)."""
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf"


class ModelFileError(ValueError):
    """A model or statistics file that cannot be loaded safely; the message names the file and why."""


def stats_candidates(model_path: str | Path) -> list[Path]:
    """Where a model's statistics may be, in order: ``name.vecnormalize.npz``, ``vec_normalize.npz``."""
    p = Path(model_path)
    return [p.with_suffix(".vecnormalize.npz"), p.parent / "vec_normalize.npz"]


def stats_path(model_path: str | Path) -> Path:
    """The statistics file of a saved model: the first of `stats_candidates` that exists (else the first)."""
    found = [c for c in stats_candidates(model_path) if c.is_file()]
    return found[0] if found else stats_candidates(model_path)[0]


def _pickled_stats(model_path: Path) -> list[Path]:
    return [
        c
        for c in (model_path.with_suffix(".vecnormalize.pkl"), model_path.parent / "vec_normalize.pkl")
        if c.is_file()
    ]


@dataclass(frozen=True)
class RunningStats:
    """Mean and variance of one observation key (as VecNormalize's ``obs_rms[key]``)."""

    mean: np.ndarray
    var: np.ndarray


def save_stats(vec_normalize: Any, path: str | Path) -> Path:
    """Write a `VecNormalize`'s observation statistics as ``.npz`` data (no pickle). Returns the path."""
    rms = vec_normalize.obs_rms
    keys = list(
        getattr(vec_normalize, "norm_obs_keys", None) or (rms.keys() if isinstance(rms, dict) else [])
    )
    arrays: dict[str, np.ndarray] = {
        "norm_obs": np.array(bool(vec_normalize.norm_obs)),
        "norm_obs_keys": np.array(keys, dtype=str),
        "clip_obs": np.array(float(vec_normalize.clip_obs)),
        "epsilon": np.array(float(vec_normalize.epsilon)),
    }
    for k in keys:
        arrays[f"mean/{k}"] = np.asarray(rms[k].mean, dtype=np.float64)
        arrays[f"var/{k}"] = np.asarray(rms[k].var, dtype=np.float64)
    out = Path(path)
    with out.open("wb") as fh:
        np.savez(fh, **arrays)
    return out


def convert_pickled_stats(pkl: str | Path, npz: str | Path) -> Path:
    """Convert a TRUSTED pickled VecNormalize file (your own training output) to ``.npz``.

    Unpickling runs code stored in the file: call this only on files you wrote yourself.
    """
    import pickle

    with Path(pkl).open("rb") as fh:
        vn = pickle.load(fh)  # explicit conversion of the user's own file
    return save_stats(vn, npz)


def _load_stats(path: Path) -> dict[str, Any] | None:
    """Statistics from an ``.npz`` (no pickle), or None if absent or normalisation was off.

    Raises:
        ModelFileError: not an ``.npz`` of statistics.
    """
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if not bool(z["norm_obs"]):
                return None
            keys = [str(k) for k in z["norm_obs_keys"]]
            return {
                "obs_rms": {k: RunningStats(z[f"mean/{k}"], z[f"var/{k}"]) for k in keys},
                "clip_obs": float(z["clip_obs"]),
                "epsilon": float(z["epsilon"]),
                "norm_obs_keys": keys,
            }
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise ModelFileError(f"{path}: not normalisation statistics saved by save_stats ({exc})") from None


def _numbers(text: Any, shape: tuple[int, ...], default: float) -> np.ndarray:
    values = [float(v) for v in re.findall(_NUMBER, str(text or ""))]
    size = int(np.prod(shape)) if shape else 1
    if len(values) == size:
        return np.array(values, dtype=np.float32).reshape(shape)
    if len(values) == 1:
        return np.full(shape, values[0], dtype=np.float32)
    return np.full(shape, default, dtype=np.float32)


def _box_space(entry: dict[str, Any]) -> Any:
    from gymnasium import spaces

    shape = tuple(int(n) for n in entry.get("_shape") or ())
    dtype = np.dtype(entry.get("dtype") or "float32")
    low, high = _numbers(entry.get("low"), shape, -np.inf), _numbers(entry.get("high"), shape, np.inf)
    return spaces.Box(low, high, shape, dtype)


def _dict_space(text: str) -> Any:
    from gymnasium import spaces

    found = re.findall(r"'(\w+)': Box\(.*?, \(([\d, ]*)\), (\w+)\)", text, re.S)
    if not found:
        raise ValueError("no Box spaces in the observation space's description")
    return spaces.Dict(
        {
            key: spaces.Box(
                -np.inf, np.inf, tuple(int(n) for n in dims.replace(" ", "").split(",") if n), dtype
            )
            for key, dims, dtype in found
        }
    )


def _space(entry: Any, what: str) -> Any:
    if not isinstance(entry, dict):
        raise ValueError(f"no {what}")
    kind = str(entry.get(":type:", ""))
    if kind.endswith("spaces.box.Box'>"):
        return _box_space(entry)
    if kind.endswith("spaces.dict.Dict'>"):
        return _dict_space(str(entry.get("spaces", "")))
    raise ValueError(f"{what} of type {kind or '?'} is not supported (Box or Dict of Box only)")


def _algorithm_and_custom_objects(path: Path) -> tuple[Any, dict[str, Any]]:
    """The SB3 algorithm class for the zip at `path`, and a replacement for every pickled entry of it.

    Raises:
        ModelFileError: not an SB3 zip, or entries this loader cannot rebuild without unpickling.
    """
    import stable_baselines3 as sb3

    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
        if not isinstance(data, dict):
            raise ValueError("its 'data' entry is not a JSON object")
        policy_init = str(data.get("policy_class", {}).get("__init__", ""))
        match = re.search(r"function (\w+)\.__init__", policy_init)
        if match is None:
            raise ValueError("its policy class is not named in the file")
        policy_name = match.group(1)
        custom: dict[str, Any] = {
            key: None for key, value in data.items() if isinstance(value, dict) and ":serialized:" in value
        }
        custom["observation_space"] = _space(data.get("observation_space"), "observation space")
        custom["action_space"] = _space(data.get("action_space"), "action space")
    except (zipfile.BadZipFile, KeyError, ValueError, OSError) as exc:
        raise ModelFileError(
            f"{path}: not a Stable-Baselines3 model this loader reads safely ({exc})"
        ) from None
    for name in ALGORITHMS:
        cls = getattr(sb3, name)
        classes = {c.__name__: c for c in cls.policy_aliases.values()}
        if policy_name in classes:
            custom["policy_class"] = classes[policy_name]
            custom["lr_schedule"] = _constant
            if isinstance(data.get("policy_kwargs"), dict) and ":serialized:" not in data["policy_kwargs"]:
                # Acting needs no optimizer; building torch's Adam imports torch._dynamo (about 2 s).
                custom["policy_kwargs"] = {
                    **data["policy_kwargs"],
                    "optimizer_class": InferenceOnlyOptimizer,
                    "optimizer_kwargs": {},
                }
            for key in ("clip_range", "clip_range_vf"):
                if key in custom:
                    custom[key] = 0.2 if key == "clip_range" else None
            return cls, custom
    raise ModelFileError(
        f"{path}: policy class {policy_name!r} is not one of Stable-Baselines3's own"
        f" ({', '.join(ALGORITHMS)}); custom policy classes would need code from the file"
    )


def _constant(_: float) -> float:
    return 0.0


class InferenceOnlyOptimizer:
    """Stands in for a loaded model's training optimizer: `SB3Policy` only acts, it never trains.

    Loading keeps the file's optimizer state as is (`state_dict` returns it), so nothing in the model is
    lost; `step` refuses. The predicted actions do not depend on the optimizer.
    """

    def __init__(self, params: Any, lr: float = 0.0, **kwargs: Any) -> None:
        self._state: dict[str, Any] = {}

    def load_state_dict(self, state_dict: dict[str, Any], strict: bool = True) -> None:
        """Keep the saved optimizer state (never used to act)."""
        self._state = state_dict

    def state_dict(self) -> dict[str, Any]:
        """The state loaded from the file."""
        return self._state

    def zero_grad(self, set_to_none: bool = True) -> None:
        """Nothing to clear."""

    def step(self, closure: Any = None) -> None:
        """Training is not supported on a policy loaded to act."""
        raise RuntimeError("an SB3Policy model is loaded to act; load it with stable_baselines3 to train")


def _load_model(path: Path) -> Any:
    try:
        import stable_baselines3  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(f"loading {path} needs Stable-Baselines3: pip install -e '.[rl]' ({exc})") from None
    cls, custom = _algorithm_and_custom_objects(path)
    try:
        return cls.load(path, device="cpu", custom_objects=custom)
    except Exception as exc:  # any failure of a foreign file is a one-line error, not a traceback
        last = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise ModelFileError(f"{path}: cannot load this Stable-Baselines3 model ({last})") from None


class SB3Policy:
    """Greedy actions of a saved Stable-Baselines3 model, normalised as in training.

    Models are cached per process (a policy is built per episode by `crossing-eval`).
    """

    name: ClassVar[str] = "sb3"
    _CACHE: ClassVar[dict[str, tuple[Any, dict[str, Any] | None, Path | None]]] = {}
    """Per model file: the model, its statistics and the statistics file they came from (None: none)."""

    def __init__(self, path: str | Path) -> None:
        """Load the model at `path` (a ``.zip``) and its VecNormalize statistics, if saved beside it."""
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"SB3 model {str(p)!r} does not exist")
        key = str(p.resolve())
        if key not in self._CACHE:
            pickled = _pickled_stats(p)
            stats = stats_path(p)
            found = stats if stats.is_file() else None
            if pickled and found is None:
                raise ModelFileError(
                    f"{pickled[0]}: pickled statistics are never loaded (a pickle can run code); convert"
                    " your own file once with agents.sb3.convert_pickled_stats to"
                    f" {stats_candidates(p)[0].name}"
                )
            self._CACHE[key] = (_load_model(p), _load_stats(found) if found else None, found)
        self.model, self.stats, self.stats_file = self._CACHE[key]
        # stats_file: the statistics file used (None: the model runs on raw observations)
        keys = getattr(self.model.observation_space, "spaces", {})
        self.uses_predictors = any(k in keys for k in PREDICTOR_KEYS)
        self.keys = tuple(keys)

    def normalise(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Observation standardised with the training statistics (VecNormalize's formula)."""
        if self.stats is None:
            return obs
        out = dict(obs)
        rms, clip = self.stats["obs_rms"], self.stats["clip_obs"]
        for k in self.stats["norm_obs_keys"]:
            m = rms[k]
            x = (np.asarray(obs[k], dtype=np.float64) - m.mean) / np.sqrt(m.var + self.stats["epsilon"])
            out[k] = np.clip(x, -clip, clip).astype(np.float32)
        return out

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """One action (float32, shape (1,)) for one observation."""
        batch = {k: np.asarray(obs[k], dtype=np.float32)[None] for k in self.keys}  # type: ignore[index]
        action, _ = self.model.predict(self.normalise(batch), deterministic=True)
        return np.clip(np.asarray(action, dtype=np.float32).reshape(1), -1.0, 1.0)

    def reset(self, seed: int | None = None) -> None:
        """Stateless (a feed-forward policy with greedy actions): nothing to forget, `seed` unused."""
