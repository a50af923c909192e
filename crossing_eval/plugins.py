"""Which policies and predictors `crossing-eval` accepts: names, plug-ins, SB3 models, checkpoints.

The task list carries plain strings (policy specs, predictor names or absolute checkpoint paths), so
worker processes and Ray tasks resolve them with `agents.make_policy` / the trajectory wrapper
themselves; nothing unpicklable crosses a process boundary.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from agents.registry import (
    BUILTIN_POLICIES,
    DEFAULT_LEARNED,
    POLICIES,
    SHIPPED_POLICIES,
    policy_entry,
    policy_names,
)
from rollout.wrappers import (
    DEGRADED_INTENTION,
    DEGRADED_PREDICTOR,
    WrapperError,
    degraded_level,
    intention_names,
    plugin_target,
)

PREDICTOR_NAMES = ("s-cgru", "cvm", "none", "oracle")
"""Built-in `--predictor` names ("oracle" is privileged); it also takes a checkpoint path."""


def sb3_available() -> bool:
    """Whether Stable-Baselines3 (the ``rl`` extra) is installed."""
    return importlib.util.find_spec("stable_baselines3") is not None


def default_policies() -> tuple[list[str], str | None]:
    """The default table's policies, and a note when the shipped learned policy has to be left out."""
    path = SHIPPED_POLICIES[DEFAULT_LEARNED]
    if not path.is_file():
        return list(BUILTIN_POLICIES), f"policy {DEFAULT_LEARNED!r} left out: {path} is missing"
    return list(POLICIES), None


def policy_spec(text: str) -> str:
    """A checked policy spec (``sb3:`` and ``mlp:`` paths made absolute, so every worker finds the file).

    Raises:
        ValueError: unknown name, module or attribute, missing file, or SB3 not installed.
    """
    prefix, _, rest = text.partition(":")
    if prefix in ("sb3", "mlp"):
        path = Path(rest).expanduser()
        if not path.is_file():
            raise ValueError(f"policy {text!r}: no such file {str(path)!r}")
        if prefix == "sb3" and not sb3_available():
            raise ValueError(f"policy {text!r} needs Stable-Baselines3: pip install -e '.[rl]'")
        text = f"{prefix}:{path.resolve()}"
    policy_entry(text)
    return text


def degraded_spec(text: str, kind: str) -> str | None:
    """A degraded oracle's name as given, or None for any other name.

    ``oracle-flip=q`` (kind 'intention', q in [0, 1]) or ``oracle-noise=sigma`` (kind 'predictor',
    sigma >= 0 m): the privileged oracles spoilt by a known amount (`predictors.degraded`).

    Raises:
        ValueError: the degraded name with a level that is not a number or out of range.
    """
    prefix = DEGRADED_INTENTION if kind == "intention" else DEGRADED_PREDICTOR
    try:
        level = degraded_level(text, prefix)
    except WrapperError as exc:
        raise ValueError(str(exc)) from None
    if level is None:
        return None
    ok = 0.0 <= level <= 1.0 if kind == "intention" else 0.0 <= level < float("inf")
    if not ok:
        want = "a probability in [0, 1]" if kind == "intention" else "a finite distance >= 0 (m)"
        raise ValueError(f"{text!r}: the level must be {want}, got {level}")
    return text


def intention_spec(text: str) -> str:
    """A built-in intention name, ``oracle-flip=q``, or a plug-in (``pkg.module:attr``, an entry point).

    A plug-in is loaded in the run's preflight, before the first episode.

    Raises:
        ValueError: anything else.
    """
    if text in intention_names() or degraded_spec(text, "intention") or plugin_target(text):
        return text
    raise ValueError(
        f"unknown intention {text!r}: not one of {', '.join(intention_names())},"
        f" {DEGRADED_INTENTION}=q, nor pkg.module:attr"
    )


def predictor_spec(text: str) -> str:
    """A built-in predictor name, ``oracle-noise=sigma``, a checkpoint file (made absolute) or a plug-in.

    Raises:
        ValueError: neither a name nor an existing file.
    """
    if text in PREDICTOR_NAMES or degraded_spec(text, "predictor"):
        return text
    path = Path(text).expanduser()
    if path.is_file():
        return str(path.resolve())
    if plugin_target(text):
        return text
    raise ValueError(
        f"unknown predictor {text!r}: not one of {', '.join(PREDICTOR_NAMES)}, pkg.module:attr,"
        " nor an existing checkpoint"
    )


def policies_help() -> str:
    """The `--policies` help text: every name accepted now, and the plug-in forms."""
    return (
        f"comma-separated policies (default: {', '.join(POLICIES)})."
        f" Names: {', '.join(policy_names())};"
        " also 'pkg.module:attr' (a function obs -> action, a policy class with config_class, or a"
        " factory(scenario=, dt=); a module in the current folder is found),"
        " installed entry points of the group 'crossing_env.policies', and 'sb3:path/model.zip'"
        " (Stable-Baselines3, with model.vecnormalize.npz beside it), 'mlp:path/policy.npz' (a learned policy"
        " stored as data, numpy only)"
    )
