"""Whether this process may fork a child: one check for every tool that forks (pools, plots, kernels)."""

from __future__ import annotations

import multiprocessing
import sys


def fork_is_safe() -> bool:
    """True where ``fork`` exists and this process has not imported torch.

    A forked child of a process that has run torch ops can hang in torch's thread pool; the default
    `crossing-eval` run never imports torch (the shipped predictor and learned policy run without it).
    """
    return "torch" not in sys.modules and "fork" in multiprocessing.get_all_start_methods()
