"""Predictor checkpoints: writing, loading and checking them (sha256 manifest, sane weights).

Checkpoints are a dict ``{"format", "config", "state_dict", "meta"}`` of plain types and tensors, loadable
with ``torch.load(weights_only=True)``; weights are stored in float16 to keep shipped files small and cast
back to float32 on load (`save_checkpoint`, `load_model`).

A flipped byte in a float16 tensor still loads and runs, and all-NaN or huge weights give predictions of
zeros or hundreds of metres without a word. So `load_model` checks every checkpoint:

- a shipped file (in ``predictors/weights/``) must match its sha256 in ``weights/manifest.json``;
- every tensor of any checkpoint must be finite and no larger in magnitude than `MAX_ABS_WEIGHT`.

``python -m studies.verify_weights`` verifies every shipped file; ``--update`` rewrites the manifest after
a deliberate retraining (``crossing-train --force`` does so for the file it replaced, through
`install_checkpoint`).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import fields
from pathlib import Path
from typing import TYPE_CHECKING

from crossing_common.files import atomic_output, give_default_permissions, write_text_atomic

if TYPE_CHECKING:
    from predictors.models import SocialRecurrent
# torch and the models are imported where they are used: the manifest checks serve torch-free inference
# (`predictors.fast_inference.load_kernel_file`) too.

SHIPPED_DIR = Path(__file__).resolve().parent / "weights"
"""Folder of the checkpoints shipped with the package."""
WEIGHTS_DIR = SHIPPED_DIR
"""The same folder, under the name the loaders (trajectory wrapper, replay, studies) use."""
MANIFEST = SHIPPED_DIR / "manifest.json"
"""``{"<file name>": "<sha256 hex>"}`` for every shipped checkpoint."""
MAX_ABS_WEIGHT = 1e3
"""Largest weight magnitude accepted. Trained models here stay below 1; float16 tops out at 65504, where
a corrupted exponent lands, and the paths such weights predict run to hundreds of metres."""
SHIPPED_PATTERNS = ("*.pt", "*.kernel.npz")
"""The shipped files the manifest lists: checkpoints and their torch-free inference arrays
(`predictors.fast_inference.save_kernel_file`)."""
CHECKPOINT_FORMAT = "crossing-env/trajectory-predictor/1"
"""Value of a checkpoint's ``format`` field."""


class CheckpointError(ValueError):
    """A checkpoint that must not be used; the message names the file and what is wrong."""


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_manifest() -> dict[str, str]:
    """The shipped manifest (empty if missing)."""
    try:
        return dict(json.loads(MANIFEST.read_text(encoding="utf-8")))
    except FileNotFoundError:
        return {}


def is_shipped(path: Path) -> bool:
    """Whether `path` lies in the shipped weights folder."""
    return path.resolve().parent == SHIPPED_DIR


def verify_shipped(path: Path) -> None:
    """Check a shipped checkpoint against the manifest; other paths pass unchecked here.

    Raises:
        CheckpointError: the file is not listed, or its bytes differ from the listed sum.
    """
    if not is_shipped(path):
        return
    expected = read_manifest().get(path.name)
    if expected is None:
        raise CheckpointError(
            f"{path}: not in {MANIFEST.name}, so it cannot be checked; run"
            " `python -m studies.verify_weights --update` if you put it there on purpose"
        )
    actual = sha256_file(path)
    if actual != expected:
        raise CheckpointError(
            f"{path}: sha256 {actual[:12]}… does not match the manifest's {expected[:12]}…; the file is"
            " corrupt or was replaced (restore it with `git checkout`, or run"
            " `python -m studies.verify_weights --update` after a deliberate retraining)"
        )


def check_weights(state: Mapping[str, object], path: Path) -> None:
    """Refuse non-finite or absurdly large weights in any checkpoint.

    Raises:
        CheckpointError: naming the tensor and the offending value.
    """
    import torch

    for name, value in state.items():
        if not isinstance(value, torch.Tensor):
            raise CheckpointError(f"{path}: state_dict[{name!r}] is a {type(value).__name__}, not a tensor")
        t = value.float()
        if not bool(torch.isfinite(t).all()):
            bad = int((~torch.isfinite(t)).sum())
            raise CheckpointError(f"{path}: {bad} non-finite value(s) (NaN or inf) in weight {name!r}")
        biggest = float(t.abs().max()) if t.numel() else 0.0
        if biggest > MAX_ABS_WEIGHT:
            raise CheckpointError(
                f"{path}: weight {name!r} has magnitude {biggest:.4g} > {MAX_ABS_WEIGHT:g}; the checkpoint is"
                " corrupt or diverged"
            )


def shipped_files() -> list[Path]:
    """Every shipped file the manifest covers (`SHIPPED_PATTERNS`), sorted."""
    return sorted(f for pattern in SHIPPED_PATTERNS for f in SHIPPED_DIR.glob(pattern))


def update_manifest(names: Sequence[str] | None = None) -> dict[str, str]:
    """Record the sums of the shipped files (all of them, or just `names`); returns the manifest."""
    manifest = read_manifest()
    files = shipped_files() if names is None else [SHIPPED_DIR / n for n in names]
    if names is None:
        manifest = {}
    for f in files:
        manifest[f.name] = sha256_file(f)
    write_text_atomic(MANIFEST, json.dumps(dict(sorted(manifest.items())), indent=1) + "\n")
    return manifest


def save_checkpoint(path: Path, model: SocialRecurrent, meta: dict[str, object]) -> None:
    """Write the checkpoint atomically (temp file + ``os.replace``); weights in float16."""
    import torch

    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": CHECKPOINT_FORMAT,
        "config": model.config.to_dict(),
        "state_dict": {k: v.detach().to(torch.float16).clone() for k, v in model.state_dict().items()},
        "meta": json.dumps(meta),
    }
    with atomic_output(path) as tmp:
        torch.save(payload, tmp)


def load_model(path: str | Path, *, verify_manifest: bool = True) -> SocialRecurrent:
    """Load a checkpoint written by :func:`save_checkpoint` with ``weights_only=True``.

    A shipped checkpoint must match its sha256 in the manifest, and no checkpoint may hold non-finite or
    absurdly large weights. Pickles that would run code are refused by ``weights_only=True``.

    Args:
        path: The checkpoint file.
        verify_manifest: False skips the manifest check only (the weight checks still run): for the
            unfinished file a training run writes beside a shipped checkpoint before it replaces it.

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file is corrupt (checksum, NaN/inf or huge weights: `CheckpointError`), not a
            predictor checkpoint, or its weights do not fit its config; the message names the file.
    """
    import torch

    from predictors.models import ModelConfig, SocialRecurrent

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"predictor checkpoint not found: {path}")
    if verify_manifest:
        verify_shipped(path)
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:
        raise ValueError(f"{path}: not a readable torch checkpoint ({type(exc).__name__}: {exc})") from exc
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        raise ValueError(f"{path}: not a crossing-env trajectory predictor checkpoint (field 'format')")
    cfg_dict = payload.get("config")
    known = {f.name for f in fields(ModelConfig)}
    if not isinstance(cfg_dict, dict) or set(cfg_dict) - known:
        raise ValueError(
            f"{path}: field 'config' must hold ModelConfig fields {sorted(known)}, got {cfg_dict!r}"
        )
    try:
        config = ModelConfig(**cfg_dict)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: invalid field 'config': {exc}") from exc
    model = SocialRecurrent(config)
    state = payload.get("state_dict")
    if not isinstance(state, dict):
        raise ValueError(f"{path}: field 'state_dict' missing or not a dict")
    check_weights(state, path)
    try:
        model.load_state_dict({k: v.float() for k, v in state.items()}, strict=True)
    except (RuntimeError, AttributeError) as exc:
        raise ValueError(f"{path}: weights do not match architecture {config.kind!r}: {exc}") from exc
    model.eval()
    return model


def checkpoint_meta(path: str | Path) -> dict[str, object]:
    """Training metadata stored in a checkpoint (budget, validation scores)."""
    import torch

    payload = torch.load(Path(path), map_location="cpu", weights_only=True)
    return json.loads(payload.get("meta", "{}"))


def weights_for(kind: str, scene: str, weights_dir: Path) -> Path | None:
    """Checkpoint of model ``kind`` for ``scene``, or ``None`` if absent.

    ``<kind>_<scene>.pt`` (the ETH/UCY ones are trained without that scene); for ``sdd``, if there is no
    ``<kind>_sdd.pt``, ``<kind>_all.pt`` (trained on all ETH/UCY recordings: a cross-dataset result).
    """
    for name in [f"{kind}_{scene}.pt"] + ([f"{kind}_all.pt"] if scene == "sdd" else []):
        if (weights_dir / name).is_file():
            return weights_dir / name
    return None


def partial_path(target: Path) -> Path:
    """A new, empty, uniquely named file beside `target` for a checkpoint still being written.

    Beside it, so that `install_checkpoint` can move it over `target` with one atomic ``os.replace``.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
    os.close(fd)
    give_default_permissions(name)
    return Path(name)


def install_checkpoint(finished: Path, target: Path) -> None:
    """Move a finished checkpoint over `target` in one ``os.replace``; a shipped target's sum follows.

    `finished` must lie in `target`'s folder (`partial_path`). It is loaded with every weight check before
    anything is touched, so a bad file leaves `target` as it was. For a shipped target the manifest entry
    is rewritten right after the replace; should that fail, the previous file is put back (from a hard
    link kept until then), so the file and its entry change together or not at all. Only a kill between
    the two steps can leave them apart, which `python -m studies.verify_weights` then reports.

    Raises:
        ValueError: `finished` is not a usable checkpoint, or not in `target`'s folder.
    """
    if finished.resolve().parent != target.resolve().parent:
        raise ValueError(f"{finished}: must be in the folder of {target} to replace it atomically")
    load_model(finished, verify_manifest=False)
    if not is_shipped(target):
        os.replace(finished, target)
        return
    backup = None
    if target.exists():
        backup = partial_path(target)
        backup.unlink()
        try:
            os.link(target, backup)
        except OSError:  # no hard links on this file system: a copy serves as well
            shutil.copy2(target, backup)
    try:
        os.replace(finished, target)
        try:
            update_manifest([target.name])
        except BaseException:
            if backup is not None:
                os.replace(backup, target)
            else:
                target.unlink(missing_ok=True)
            raise
    finally:
        if backup is not None:
            backup.unlink(missing_ok=True)
