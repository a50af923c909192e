"""Writing scenarios: `ScenarioConfig` → TOML text (with `tomli_w`) that loads back to an equal config."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import tomli_w

from crossing_common.files import write_text_atomic
from scenarios.config import ScenarioConfig
from scenarios.validation import to_data, validate_scenario


def to_toml(data: Mapping[str, Any]) -> str:
    """Nested dicts/lists of TOML-representable values as TOML text (the inverse of `tomllib.loads`)."""
    return tomli_w.dumps(data)


def dump_scenario(cfg: ScenarioConfig) -> str:
    """TOML text for a scenario; `load`/`parse_scenario` of it gives back an equal `ScenarioConfig`.

    Every field is written, defaults included, so a dumped file documents the exact configuration.
    """
    return to_toml(to_data(cfg))


def save_scenario(cfg: ScenarioConfig, path: str | os.PathLike[str]) -> Path:
    """Validate `cfg` and write it to `path` atomically (temp file + `os.replace`, nothing half-written).

    Raises:
        ScenarioError: if `cfg` is invalid; the target file is then left untouched.
    """
    target = Path(path)
    validate_scenario(cfg, str(target))
    write_text_atomic(target, dump_scenario(cfg))
    return target
