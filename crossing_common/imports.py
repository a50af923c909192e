"""Importing a user's plug-in module by name, from an installed package or from the current folder."""

from __future__ import annotations

import importlib
import os
import sys
from types import ModuleType


def import_plugin_module(module: str) -> ModuleType:
    """Import `module`, looking in the current folder too, as ``python -m`` would.

    The folder is appended to ``sys.path`` only when the module is not found otherwise, so installed
    modules keep precedence, and worker processes started afterwards (which inherit ``sys.path``) find it
    as well.

    Raises:
        ModuleNotFoundError: neither installed nor in the current folder.
    """
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        here = os.getcwd()
        if exc.name != module.split(".")[0] or here in sys.path or "" in sys.path:
            raise
        sys.path.append(here)
        return importlib.import_module(module)
