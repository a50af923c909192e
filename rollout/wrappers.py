"""The one table of predictors: ``--intention`` and ``--predictor`` names → forecasters in the one wrapper.

Every predictor is a forecaster (`predictors.forecast`) and reaches the policy through the one observation
wrapper (`predictors.forecast_wrapper.ForecastObservation`). Every tool builds them here, so a name means the
same predictor everywhere and one that cannot be built is an error everywhere (`WrapperError`, a
``ValueError``): nothing runs on without the predictor that was asked for. The opt-out is explicit: the
name ``none``. The ``oracle`` entries read the world's ground truth; they exist as privileged upper bounds
and are only used when asked for by name.

Adding a predictor is one row in `INTENTION_WRAPPERS` or `TRAJECTORY_WRAPPERS` (and its module). A user's
own predictor needs no row: ``--predictor pkg.module:attr`` / ``--intention pkg.module:attr`` (or the name of
an installed entry point of the group `ENTRY_POINT_GROUP`) names a forecaster class or a factory called
with no arguments, once per env (`plugin_target`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from crossing_common.imports import import_plugin_module

NONE = "none"
"""The explicit opt-out: no wrapper of this kind."""
DEFAULT_INTENTION = "qlb"
"""Intention wrapper for a policy that reads predictions when the caller names none."""
DEFAULT_PREDICTOR = "s-cgru"
"""Trajectory predictor for a policy that reads predictions when the caller names none."""


ENTRY_POINT_GROUP = "crossing_env.predictors"
"""Entry-point group of installed predictor plug-ins: ``name = "pkg.module:attr"`` (a forecaster factory)."""


class WrapperError(ValueError):
    """A wrapper name that is unknown or a wrapper that cannot be built (missing module, bad weights)."""


@dataclass(frozen=True)
class WrapperEntry:
    """How to build one forecaster: ``module:attr`` imported on first use (path models load torch)."""

    target: str
    """``"pkg.module:Class"`` of the forecaster (`predictors.forecast.Forecaster`)."""
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Its keyword arguments."""
    privileged: bool = False
    """Reads the ground truth (an oracle bound, never a deployable predictor)."""
    summary: str = ""
    """One line for ``--help`` and the docs."""


INTENTION_WRAPPERS: dict[str, WrapperEntry] = {
    "qlb": WrapperEntry(
        "predictors.intention:IntentionModel",
        {"variant": "qlb"},
        summary="quantum-like Bayesian crossing intention (Song et al.)",
    ),
    "classical": WrapperEntry(
        "predictors.intention:IntentionModel",
        {"variant": "cbm"},
        summary="the same model without the interference term",
    ),
    "learned": WrapperEntry(
        "predictors.learned_intent:LearnedIntent",
        summary="logistic regression on observation features, fitted on simulated training seeds",
    ),
    "oracle": WrapperEntry(
        "predictors.oracle:IntentOracle", privileged=True, summary="the true decision (upper bound)"
    ),
}
"""``--intention`` names (besides ``none``): wrappers that add ``crossing_intention`` and
``crossing_intent`` (the real ones also their release bound ``crossing_intent_bound``)."""

TRAJECTORY_WRAPPERS: dict[str, WrapperEntry] = {
    "s-cgru": WrapperEntry(
        "predictors.trajectory_wrapper:PathModel",
        {"model": "s-cgru"},
        summary="social convolutional GRU (Xu et al.), shipped weights",
    ),
    "cvm": WrapperEntry(
        "predictors.trajectory_wrapper:PathModel",
        {"model": "cvm"},
        summary="constant-velocity model (the trivial baseline)",
    ),
    "oracle": WrapperEntry(
        "predictors.oracle:PathOracle", privileged=True, summary="the true future (upper bound)"
    ),
}
"""``--predictor`` names (besides ``none`` and checkpoint paths): wrappers that add ``predicted_paths``."""

CHECKPOINT_WRAPPER = "predictors.trajectory_wrapper:PathModel"
"""The forecaster a ``--predictor`` checkpoint path is loaded into (``model=path``)."""


DEGRADED_INTENTION = "oracle-flip"
"""``oracle-flip=q``: the intention oracle wrong for each track with probability q (`predictors.degraded`)."""
DEGRADED_PREDICTOR = "oracle-noise"
"""``oracle-noise=sigma``: the path oracle with a horizon-growing error, sigma (m) at 4.8 s
(`predictors.degraded`)."""


def degraded_level(name: str, prefix: str) -> float | None:
    """The level of a degraded-oracle name (``oracle-flip=0.2`` → 0.2), None for any other name.

    Raises:
        WrapperError: the prefix with a value that is not a number.
    """
    head, sep, value = name.partition("=")
    if not sep or head != prefix:
        return None
    try:
        return float(value)
    except ValueError:
        raise WrapperError(f"{name!r}: {prefix}= needs a number, got {value!r}") from None


def intention_names() -> tuple[str, ...]:
    """Every ``--intention`` value: the table's names and ``none``."""
    return (*INTENTION_WRAPPERS, NONE)


def predictor_names() -> tuple[str, ...]:
    """Every ``--predictor`` name (a checkpoint path is accepted too): the table's names and ``none``."""
    return (*TRAJECTORY_WRAPPERS, NONE)


def installed_predictors() -> dict[str, str]:
    """Installed plug-in predictors: entry-point name → ``"pkg.module:attr"`` (nothing imported)."""
    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def _dotted(text: str) -> bool:
    return bool(text) and all(part.isidentifier() for part in text.split("."))


def plugin_target(name: str) -> str | None:
    """``pkg.module:attr`` of a plug-in predictor name, None for any other name.

    A name is a plug-in when it has that form or is an installed entry point of `ENTRY_POINT_GROUP`
    (built-in names, degraded oracles and checkpoint files are resolved before).
    """
    found = installed_predictors().get(name)
    if found is not None:
        return found
    module, sep, attr = name.partition(":")
    return name if sep and _dotted(module) and _dotted(attr) else None


def _load(target: str, what: str) -> Any:
    module, _, attr = target.partition(":")
    try:
        obj: Any = import_plugin_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as exc:
        raise WrapperError(f"{what}: cannot load {target} ({exc})") from exc
    except Exception as exc:  # the plug-in's own import-time code raised: one line, not a traceback
        raise WrapperError(f"{what}: importing {module} raised {type(exc).__name__}: {exc}") from exc
    return obj


def _plugin(env: Any, name: str, target: str, what: str, kind: str) -> Any:
    """`env` under the one forecast wrapper holding the plug-in forecaster `target` makes."""
    from predictors.forecast import ForecastSpec
    from predictors.forecast_wrapper import ForecastObservation

    factory = _load(target, what)
    if not callable(factory):
        raise WrapperError(f"{what}: {target} is not a forecaster class or factory")
    try:
        forecaster = factory()
    except Exception as exc:
        raise WrapperError(f"{what}: {target}() raised {type(exc).__name__}: {exc}") from exc
    spec = getattr(forecaster, "spec", None)
    if isinstance(spec, ForecastSpec) and not getattr(spec, kind):
        flag = "paths=True" if kind == "paths" else "intent=True"
        raise WrapperError(f"{what}: {target} does not forecast {kind} (its ForecastSpec needs {flag})")
    try:
        return ForecastObservation(env, forecaster, name)
    except ValueError as exc:
        raise WrapperError(str(exc)) from exc


def _build(env: Any, entry: WrapperEntry, what: str, name: str, **extra: Any) -> Any:
    """`env` under the one forecast wrapper holding the forecaster `entry` builds."""
    from predictors.forecast_wrapper import ForecastObservation

    factory = _load(entry.target, what)
    try:
        return ForecastObservation(env, factory(**{**entry.kwargs, **extra}), name)
    except WrapperError:
        raise
    except (OSError, ValueError, RuntimeError, KeyError) as exc:
        # predictors.checkpoints.CheckpointError is a ValueError: corrupt or tampered weights land here.
        raise WrapperError(f"{what}: {exc}") from exc


def wrap_intention(env: Any, name: str) -> tuple[Any, str | None]:
    """`env` under the intention wrapper `name`, and its label (None for ``none``).

    Raises:
        WrapperError: unknown name, or the wrapper cannot be built.
    """
    if name == NONE:
        return env, None
    flip = degraded_level(name, DEGRADED_INTENTION)
    if flip is not None:
        entry = WrapperEntry("predictors.degraded:FlippedIntent", {"flip": flip}, privileged=True)
        return _build(env, entry, f"intention {name!r}", name), f"intention:{name}"
    if name not in INTENTION_WRAPPERS:
        target = plugin_target(name)
        if target is not None:
            return _plugin(env, name, target, f"intention {name!r}", "intent"), f"intention:{name}"
        raise WrapperError(
            f"intention {name!r}: unknown; choose from {', '.join(intention_names())} or pkg.module:attr"
        )
    return _build(env, INTENTION_WRAPPERS[name], f"intention {name!r}", name), f"intention:{name}"


def wrap_predictor(env: Any, name: str) -> tuple[Any, str | None]:
    """`env` under the trajectory predictor `name` (a table name or a checkpoint path), and its label.

    Raises:
        WrapperError: unknown name, missing checkpoint, or a model that cannot be loaded.
    """
    if name == NONE:
        return env, None
    what = f"predictor {name!r}"
    sigma = degraded_level(name, DEGRADED_PREDICTOR)
    if sigma is not None:
        entry = WrapperEntry("predictors.degraded:NoisyOraclePaths", {"sigma": sigma}, privileged=True)
        return _build(env, entry, what, name), f"trajectory:{name}"
    if name in TRAJECTORY_WRAPPERS:
        return _build(env, TRAJECTORY_WRAPPERS[name], what, name), f"trajectory:{name}"
    if not Path(name).expanduser().is_file():
        target = plugin_target(name)
        if target is not None:
            return _plugin(env, name, target, what, "paths"), f"trajectory:{name}"
        raise WrapperError(
            f"{what}: not one of {', '.join(predictor_names())}, pkg.module:attr, nor an existing checkpoint"
        )
    entry = WrapperEntry(CHECKPOINT_WRAPPER)
    return _build(env, entry, what, name, model=str(Path(name).expanduser())), f"trajectory:{name}"


def wrap(env: Any, intention: str = NONE, predictor: str = NONE) -> tuple[Any, list[str]]:
    """`env` with the intention wrapper first and the trajectory predictor second, and the labels used.

    The order is fixed, so a policy sees the same observation in every tool. On an error the env is closed.
    """
    used: list[str] = []
    try:
        env, label = wrap_intention(env, intention)
        used += [label] if label else []
        env, label = wrap_predictor(env, predictor)
        used += [label] if label else []
    except BaseException:
        env.close()
        raise
    return env, used
