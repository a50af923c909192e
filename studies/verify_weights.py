"""Verify the shipped predictor checkpoints against their sha256 manifest, or rewrite the manifest.

``python -m studies.verify_weights`` checks every ``predictors/weights/*.pt`` and ``*.kernel.npz`` (exit 1
if one fails);
``--update`` rewrites ``predictors/weights/manifest.json`` from the files present, after a deliberate
retraining (``crossing-train --force`` already updates the entry of the file it replaced).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from predictors import checkpoints
from predictors.checkpoints import CheckpointError, update_manifest, verify_shipped


def main(argv: Sequence[str] | None = None) -> int:
    """Verify the shipped checkpoints (exit 1 if one fails) or, with ``--update``, rewrite the manifest."""
    parser = argparse.ArgumentParser(
        prog="python -m studies.verify_weights", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--update", action="store_true", help="rewrite the manifest from the files present")
    args = parser.parse_args(argv)
    if args.update:
        print(f"wrote {checkpoints.MANIFEST} ({len(update_manifest())} files)")
        return 0
    files = checkpoints.shipped_files()
    bad = 0
    for f in files:
        try:
            verify_shipped(f)
        except CheckpointError as exc:
            bad += 1
            print(exc, file=sys.stderr)
    print(f"{len(files) - bad} ok, {bad} failed")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
