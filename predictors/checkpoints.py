"""Checked predictor weights: sha256 manifest of the shipped checkpoints and sanity checks on any checkpoint.

A flipped byte in a float16 tensor still loads and runs, and all-NaN or huge weights give predictions of
zeros or hundreds of metres without a word. So `load_model` (`predictors.train`) checks every checkpoint:

- a shipped file (in ``predictors/weights/``) must match its sha256 in ``weights/manifest.json``;
- every tensor of any checkpoint must be finite and no larger in magnitude than `MAX_ABS_WEIGHT`.

``python -m predictors.checkpoints`` verifies every shipped file; ``--update`` rewrites the manifest after
a deliberate retraining (``crossing-train --force`` does so for the file it replaced).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path

import torch

from crossing_common.files import write_text_atomic

SHIPPED_DIR = Path(__file__).resolve().parent / "weights"
"""Folder of the checkpoints shipped with the package."""
MANIFEST = SHIPPED_DIR / "manifest.json"
"""``{"<file name>": "<sha256 hex>"}`` for every shipped checkpoint."""
MAX_ABS_WEIGHT = 1e3
"""Largest weight magnitude accepted. Trained models here stay below 1; float16 tops out at 65504, where
a corrupted exponent lands, and the paths such weights predict run to hundreds of metres."""


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
            " `python -m predictors.checkpoints --update` if you put it there on purpose"
        )
    actual = sha256_file(path)
    if actual != expected:
        raise CheckpointError(
            f"{path}: sha256 {actual[:12]}… does not match the manifest's {expected[:12]}…; the file is"
            " corrupt or was replaced (restore it with `git checkout`, or run"
            " `python -m predictors.checkpoints --update` after a deliberate retraining)"
        )


def check_weights(state: Mapping[str, object], path: Path) -> None:
    """Refuse non-finite or absurdly large weights in any checkpoint.

    Raises:
        CheckpointError: naming the tensor and the offending value.
    """
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


def update_manifest(names: Sequence[str] | None = None) -> dict[str, str]:
    """Record the sums of the shipped files (all of them, or just `names`); returns the manifest."""
    manifest = read_manifest()
    files = sorted(SHIPPED_DIR.glob("*.pt")) if names is None else [SHIPPED_DIR / n for n in names]
    if names is None:
        manifest = {}
    for f in files:
        manifest[f.name] = sha256_file(f)
    write_text_atomic(MANIFEST, json.dumps(dict(sorted(manifest.items())), indent=1) + "\n")
    return manifest


def main(argv: Sequence[str] | None = None) -> int:
    """Verify the shipped checkpoints (exit 1 if one fails) or, with ``--update``, rewrite the manifest."""
    parser = argparse.ArgumentParser(
        prog="python -m predictors.checkpoints", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--update", action="store_true", help="rewrite the manifest from the files present")
    args = parser.parse_args(argv)
    if args.update:
        print(f"wrote {MANIFEST} ({len(update_manifest())} files)")
        return 0
    bad = 0
    for f in sorted(SHIPPED_DIR.glob("*.pt")):
        try:
            verify_shipped(f)
        except CheckpointError as exc:
            bad += 1
            print(exc, file=sys.stderr)
    print(f"{len(list(SHIPPED_DIR.glob('*.pt'))) - bad} ok, {bad} failed")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
