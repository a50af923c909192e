"""Learned policies stored as plain data: an MLP's weights and its observation statistics in one ``.npz``.

A policy trained with Stable-Baselines3 (``MultiInputPolicy``: each observation key flattened and
concatenated, then an MLP) is exported by `export_sb3` into arrays only — no pickle, no code — and acted on
here with numpy, so a shipped learned policy needs neither Stable-Baselines3 nor torch to run, and a policy
file cannot run code (``np.load(allow_pickle=False)``).

File layout (every entry an array):

- ``format``: ``"crossing-mlp-1"``; ``keys``: the observation keys, in the order they are concatenated;
- ``mean/<key>``, ``var/<key>``: VecNormalize's running statistics; ``clip_obs``, ``epsilon``: its clip and
  epsilon (observations are standardised, then clipped);
- ``weight/<i>``, ``bias/<i>``: the actor's linear layers in order (tanh between them, none after the last),
  whose output is the Gaussian's mean action, clipped to [−1, 1] (the greedy action);
- ``shielded``: whether the policy was trained to act through `agents.shield.YieldingShield` (the registry
  then deploys it through the shield, as it was trained); ``residual_scale``: 0, or the m/s² per unit of
  action of a policy trained as a residual on the rule's acceleration (`YieldingShield.apply`);
  ``residual_offset`` (optional, 0 when absent): added to a residual policy's action before the shield
  clips it to [−1, 1] (1: the untrained actor asks for the most the envelope allows).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from agents.view import ObsLike

__all__ = ["FORMAT", "MLPPolicy", "PolicyFileError", "export_sb3", "load_mlp"]

FORMAT = "crossing-mlp-1"
"""Value of the ``format`` entry of a policy file of this layout."""


class PolicyFileError(ValueError):
    """A policy file that cannot be read as this layout; the message names the file and the entry."""


@dataclass(frozen=True)
class MLPWeights:
    """The arrays of one policy file, checked."""

    keys: tuple[str, ...]
    """Observation keys, in concatenation order."""
    mean: dict[str, np.ndarray]
    """VecNormalize's running mean per key."""
    var: dict[str, np.ndarray]
    """VecNormalize's running variance per key."""
    clip_obs: float
    """Standardised observations are clipped to ±clip_obs."""
    epsilon: float
    """Added to the variance before the square root."""
    layers: tuple[tuple[np.ndarray, np.ndarray], ...]
    """(weight (out, in), bias (out,)) of each linear layer."""
    shielded: bool
    """Deploy through the yielding shield."""
    residual_scale: float = 0.0
    """> 0: the action is a residual on the rule's acceleration, this many m/s² per unit."""
    residual_offset: float = 0.0
    """Added to the residual action before it is clipped to [−1, 1] (`YieldingShield.apply`)."""


def load_mlp(path: str | Path) -> MLPWeights:
    """Read and check a policy file (never unpickles).

    Raises:
        PolicyFileError: unreadable, another format, or inconsistent shapes (the message names the entry).
    """
    p = Path(path)
    try:
        with np.load(p, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError) as exc:
        raise PolicyFileError(
            f"{p}: not a readable .npz policy file without pickled objects ({exc})"
        ) from None
    fmt = str(arrays.get("format", ""))
    if fmt != FORMAT:
        raise PolicyFileError(f"{p}: entry 'format' is {fmt!r}, expected {FORMAT!r}")
    keys = tuple(str(k) for k in arrays["keys"])
    layers = []
    i = 0
    while f"weight/{i}" in arrays:
        w, b = arrays[f"weight/{i}"].astype(np.float64), arrays[f"bias/{i}"].astype(np.float64)
        if w.ndim != 2 or b.shape != (w.shape[0],) or (layers and layers[-1][0].shape[0] != w.shape[1]):
            raise PolicyFileError(
                f"{p}: entry 'weight/{i}' has shape {w.shape}, inconsistent with its layers"
            )
        layers.append((w, b))
        i += 1
    if not layers or layers[-1][0].shape[0] != 1:
        raise PolicyFileError(
            f"{p}: the last layer must give one action, got {layers and layers[-1][0].shape}"
        )
    width = sum(int(arrays[f"mean/{k}"].size) for k in keys)
    if layers[0][0].shape[1] != width:
        raise PolicyFileError(
            f"{p}: entry 'weight/0' expects {layers[0][0].shape[1]} inputs, keys give {width}"
        )
    return MLPWeights(
        keys=keys,
        mean={k: arrays[f"mean/{k}"].astype(np.float64) for k in keys},
        var={k: arrays[f"var/{k}"].astype(np.float64) for k in keys},
        clip_obs=float(arrays["clip_obs"]),
        epsilon=float(arrays["epsilon"]),
        layers=tuple(layers),
        shielded=bool(arrays["shielded"]),
        residual_scale=float(arrays["residual_scale"]) if "residual_scale" in arrays else 0.0,
        residual_offset=float(arrays["residual_offset"]) if "residual_offset" in arrays else 0.0,
    )


class MLPPolicy:
    """The greedy action of an exported actor network, in numpy (one observation or a batch)."""

    uses_predictors = False

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.weights = load_mlp(self.path)

    def features(self, obs: ObsLike) -> np.ndarray:
        """(B, F) standardised, clipped and concatenated observation of one or a batch of observations."""
        w = self.weights
        parts = []
        for key in w.keys:
            value = np.asarray(obs[key], dtype=np.float64)
            mean = w.mean[key]
            lead = value.shape[: value.ndim - mean.ndim]
            z = np.clip((value - mean) / np.sqrt(w.var[key] + w.epsilon), -w.clip_obs, w.clip_obs)
            parts.append(z.reshape(int(np.prod(lead)), -1))
        return np.concatenate(parts, axis=1)

    batched: ClassVar[bool] = True
    """Acts for a batch of episodes in one call, each element as alone (`agents.policy_is_batched`)."""

    def __call__(self, obs: ObsLike) -> np.ndarray:
        """The greedy action(s): float32 of shape (1,) for one observation, (B, 1) for a batch.

        The layers run one row at a time: a matrix product over a whole batch may add up in another order
        than over one row (BLAS picks its kernel by shape), and an element must get the action it gets
        alone to the last bit (`batched`). The features, the bulk of the small-array work, are batched.
        """
        rows = self.features(obs)
        out = np.empty((rows.shape[0], self.weights.layers[-1][0].shape[0]))
        for r in range(rows.shape[0]):
            out[r] = self._forward(rows[r : r + 1])[0]
        action = np.clip(out, -1.0, 1.0).astype(np.float32)
        return action.reshape(1) if action.shape[0] == 1 else action

    def _forward(self, x: np.ndarray) -> np.ndarray:
        """The actor network on (1, F) features."""
        layers = self.weights.layers
        for i, (w, b) in enumerate(layers):
            x = x @ w.T + b
            if i < len(layers) - 1:
                x = np.tanh(x)
        return x

    def reset(self, seed: int | None = None) -> None:
        """Stateless: nothing to reset."""


def export_sb3(
    model: Any,
    vec_normalize: Any,
    path: str | Path,
    *,
    shielded: bool = False,
    residual_scale: float = 0.0,
    residual_offset: float = 0.0,
) -> Path:
    """Write an SB3 ``MultiInputPolicy`` actor with tanh MLP and its VecNormalize statistics as a policy file.

    Only the parts that act are written: the actor's layers (``mlp_extractor.policy_net`` then
    ``action_net``) and the observation statistics; the critic and the optimiser are left out.
    """
    state = {k: v.detach().cpu().numpy() for k, v in model.policy.state_dict().items()}
    keys = list(model.observation_space.spaces)
    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT), "keys": np.array(keys, dtype=str)}
    rms = vec_normalize.obs_rms
    for k in keys:
        arrays[f"mean/{k}"] = np.asarray(rms[k].mean, dtype=np.float64)
        arrays[f"var/{k}"] = np.asarray(rms[k].var, dtype=np.float64)
    arrays["clip_obs"] = np.array(float(vec_normalize.clip_obs))
    arrays["epsilon"] = np.array(float(vec_normalize.epsilon))
    hidden = sorted(
        int(name.split(".")[2])
        for name in state
        if name.startswith("mlp_extractor.policy_net.") and "weight" in name
    )
    names = [f"mlp_extractor.policy_net.{i}" for i in hidden] + ["action_net"]
    for i, name in enumerate(names):
        arrays[f"weight/{i}"] = state[f"{name}.weight"].astype(np.float32)
        arrays[f"bias/{i}"] = state[f"{name}.bias"].astype(np.float32)
    arrays["shielded"] = np.array(bool(shielded))
    arrays["residual_scale"] = np.array(float(residual_scale))
    arrays["residual_offset"] = np.array(float(residual_offset))
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".partial.npz")
    np.savez(tmp, **arrays)  # type: ignore[arg-type]  # string keys with '/' are valid npz member names
    tmp.replace(out)
    return out
