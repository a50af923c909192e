"""The shipped learned-intent weights: one JSON file, checked against its own sha256 manifest, no pickle.

``predictors/weights/learned_intent.json`` holds everything fitted on the training seeds by
``python -m studies.train_learned_intent``: the logistic-regression heads of the learned model, the
Platt calibration of the QLB and classical ``crossing_intent``, the rule baseline's rates and the release
risk bound. ``learned_intent.sha256.json`` lists its sha256 (a separate manifest: the checkpoint manifest
lists the ``.pt`` files only). Loading refuses a file whose bytes differ from the listed sum.
"""

from __future__ import annotations

import hashlib
import json
import math
from functools import cache
from pathlib import Path
from typing import Any

WEIGHTS_PATH = Path(__file__).resolve().parent / "weights" / "learned_intent.json"
"""The shipped weights file (JSON)."""
MANIFEST_PATH = WEIGHTS_PATH.with_name("learned_intent.sha256.json")
"""``{"learned_intent.json": "<sha256 hex>"}``."""
FORMAT = "crossing-env/learned-intent/1"
"""Value of the weights file's ``format`` field."""
CROSSING_INTENT_BOUND_KEY = "crossing_intent_bound"
"""(1,) observation key an intent predictor adds beside ``crossing_intent``: its release risk bound (a
calibrated intent at or below it may release a legal wait; chosen on the training seeds)."""


class IntentWeightsError(ValueError):
    """Weights that must not be used (missing, tampered with, or malformed)."""


def sha256_bytes(data: bytes) -> str:
    """Hex sha256 of `data`."""
    return hashlib.sha256(data).hexdigest()


def read_weights(path: Path = WEIGHTS_PATH, manifest: Path | None = None) -> dict[str, Any]:
    """The weights as plain JSON data, after checking the file's sha256 against the manifest.

    Args:
        path: The weights file.
        manifest: The manifest to check against (default: next to `path`).

    Raises:
        IntentWeightsError: the file or manifest is missing, the sum differs, or the format is unknown.
    """
    manifest = manifest or path.with_name(MANIFEST_PATH.name)
    try:
        data = path.read_bytes()
        sums = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise IntentWeightsError(
            f"learned intent weights: cannot read {path.name} / {manifest.name}: {exc}"
        ) from exc
    expected = sums.get(path.name)
    actual = sha256_bytes(data)
    if expected != actual:
        raise IntentWeightsError(
            f"{path.name}: sha256 {actual[:12]}… does not match the manifest's {str(expected)[:12]}…;"
            " restore it or regenerate it with `python -m studies.train_learned_intent`"
        )
    weights = json.loads(data.decode("utf-8"))
    if weights.get("format") != FORMAT:
        raise IntentWeightsError(f"{path.name}: format {weights.get('format')!r}, expected {FORMAT!r}")
    for value in _numbers(weights):
        if not math.isfinite(value):
            raise IntentWeightsError(f"{path.name}: non-finite number in the weights")
    return weights


def _numbers(value: Any) -> list[float]:
    if isinstance(value, bool):
        return []
    if isinstance(value, int | float):
        return [float(value)]
    if isinstance(value, dict):
        return [x for v in value.values() for x in _numbers(v)]
    if isinstance(value, list):
        return [x for v in value for x in _numbers(v)]
    return []


@cache
def shipped_weights() -> dict[str, Any]:
    """The shipped weights (read and checked once per process)."""
    return read_weights()


def release_threshold(model: str) -> float:
    """The release risk bound of `model` (learned, qlb, classical), chosen by driving on selection seeds."""
    return float(shipped_weights()["release"]["models"][model]["threshold"])


def platt(raw: Any, coef: tuple[float, float] | list[float]) -> Any:
    """Platt calibration ``sigmoid(a * logit(raw) + b)`` of raw probabilities (numpy arrays or floats)."""
    import numpy as np

    a, b = float(coef[0]), float(coef[1])
    p = np.clip(np.asarray(raw, dtype=np.float64), 1e-6, 1.0 - 1e-6)
    z = a * np.log(p / (1.0 - p)) + b
    return 0.5 * (1.0 + np.tanh(0.5 * z))
