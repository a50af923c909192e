"""Stable-Baselines3 models as driving policies: `SB3Policy("model.zip")(obs) -> action`.

A model trained on `crossing_env/Crossing-v0` (SB3's ``MultiInputPolicy`` on the dict observation) is
loaded with the `VecNormalize` statistics saved beside it (``model.vecnormalize.pkl``, as
`examples/ppo_crossing.py` writes them), and acts greedily. If the model's observation has the predictor
keys (``crossing_intention``, ``predicted_paths``) the policy asks for the prediction wrappers.
Stable-Baselines3 is the optional ``rl`` extra: ``pip install -e ".[rl]"``.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from agents.view import ObsLike

PREDICTOR_KEYS = ("crossing_intention", "predicted_paths")
"""Observation keys that the prediction wrappers add."""


def stats_path(model_path: str | Path) -> Path:
    """Where the VecNormalize statistics of a saved model live: ``name.zip`` → ``name.vecnormalize.pkl``."""
    p = Path(model_path)
    return p.with_suffix(".vecnormalize.pkl")


def _load_model(path: Path) -> Any:
    try:
        import stable_baselines3 as sb3
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(f"loading {path} needs Stable-Baselines3: pip install -e '.[rl]' ({exc})") from None
    errors = []
    for cls_name in ("PPO", "A2C", "SAC", "TD3", "DDPG"):
        cls = getattr(sb3, cls_name)
        try:
            return cls.load(path, device="cpu")
        except (KeyError, TypeError, ValueError, AttributeError, RuntimeError) as exc:
            errors.append(f"{cls_name}: {exc}")
    raise ValueError(f"{path}: not a Stable-Baselines3 model this version can load ({'; '.join(errors)})")


class SB3Policy:
    """Greedy actions of a saved Stable-Baselines3 model, normalised as in training.

    Models are cached per process (a policy is built per episode by `crossing-eval`).
    """

    name: ClassVar[str] = "sb3"
    _CACHE: ClassVar[dict[str, tuple[Any, dict[str, Any] | None]]] = {}

    def __init__(self, path: str | Path) -> None:
        """Load the model at `path` (a ``.zip``) and its VecNormalize statistics, if saved beside it."""
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"SB3 model {str(p)!r} does not exist")
        key = str(p.resolve())
        if key not in self._CACHE:
            self._CACHE[key] = (_load_model(p), _load_stats(stats_path(p)))
        self.model, self.stats = self._CACHE[key]
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

    def reset(self) -> None:
        """Stateless (feed-forward policy)."""


def _load_stats(path: Path) -> dict[str, Any] | None:
    """VecNormalize statistics (obs_rms per key, clip, epsilon) from SB3's pickle, or None if absent."""
    if not path.is_file():
        return None
    with path.open("rb") as fh:
        vn = pickle.load(fh)  # the user's own training artefact, as SB3's VecNormalize.load does
    if not getattr(vn, "norm_obs", False):
        return None
    keys = list(getattr(vn, "norm_obs_keys", None) or vn.obs_rms.keys())
    return {
        "obs_rms": vn.obs_rms,
        "clip_obs": float(vn.clip_obs),
        "epsilon": float(vn.epsilon),
        "norm_obs_keys": keys,
    }
