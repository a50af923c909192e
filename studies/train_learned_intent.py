"""Train the learned intent model and write its shipped weights.

The command line of `predictors.learned_intent_train` (the library keeps no script entry point).

    python -m studies.train_learned_intent --episodes 8 --seed 0
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path

from predictors.learned_intent_train import WEIGHTS_PATH, train, write_weights


def main(argv: Sequence[str] | None = None) -> int:
    """Train and write the shipped weights."""
    parser = argparse.ArgumentParser(
        prog="python -m studies.train_learned_intent", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--episodes", type=int, default=8, help="training seeds per world")
    parser.add_argument("--seed", type=int, default=0, help="first training seed")
    parser.add_argument("--out", type=Path, default=WEIGHTS_PATH, help="weights file to write")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1, got {args.episodes}")
    start = time.perf_counter()
    weights = train(args.episodes, args.seed)
    digest = write_weights(weights, args.out)
    release = weights["release"]
    print(
        f"wrote {args.out.name} (sha256 {digest[:12]}…) in {time.perf_counter() - start:.0f} s;"
        f" release bounds {json.dumps(release['models'])}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
