"""The house style is enforced, not hoped for: ruff must pass on the whole repository."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.skipif(shutil.which("ruff") is None, reason="ruff is not installed (it is in the 'test' extra)")
@pytest.mark.parametrize("command", [["ruff", "check", "."], ["ruff", "format", "--check", "."]])
def test_ruff_is_clean(command):
    result = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr


def _compiled_kernels(module):
    from numba.core.registry import CPUDispatcher

    return {
        name: obj
        for name, obj in vars(module).items()
        if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == module.__name__
    }


def _modules_with_kernels() -> list[str]:
    """Every module of the packages that defines a numba kernel (found, so a new one is not forgotten)."""
    names = []
    for package in (
        "crossing_common",
        "scenarios",
        "crossing_env",
        "predictors",
        "agents",
        "crossing_replay",
        "crossing_eval",
    ):
        for path in sorted((REPO / package).rglob("*.py")):
            if "@njit" in path.read_text(encoding="utf-8"):
                names.append(".".join(path.relative_to(REPO).with_suffix("").parts))
    return names


def test_kernel_modules_are_found() -> None:
    found = _modules_with_kernels()
    assert {
        "crossing_env.pedestrians.social_force",
        "predictors.fast_inference",
        "predictors.pooling",
    } <= set(found)


@pytest.mark.parametrize("module_name", _modules_with_kernels())
def test_kernels_only_call_kernels_of_their_own_module(module_name):
    """numba refreshes a kernel's on-disk cache only when the kernel's own file changes; a kernel calling a
    kernel of another module would keep running that callee's old code after an edit."""
    import importlib

    from numba.core.registry import CPUDispatcher

    module = importlib.import_module(module_name)
    kernels = _compiled_kernels(module)
    assert kernels, f"{module_name} has no compiled kernels (update this list)"
    for name, kernel in kernels.items():
        for called in kernel.py_func.__code__.co_names:
            target = vars(module).get(called)
            if isinstance(target, CPUDispatcher):
                assert target.py_func.__module__ == module_name, (
                    f"{module_name}.{name} calls {target.py_func.__module__}.{called}"
                )
