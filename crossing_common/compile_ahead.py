"""Compiling numba kernels ahead, in a second process, in the reverse order of their first calls.

On a fresh install every cached numba kernel (``cache=True``) compiles the first time it is called, one
after the other, on one core. A second process can compile the same kernels into numba's on-disk cache,
if it knows their argument types before the first process reaches them: `record_signatures` learns them
by running the code once with each kernel's Python function in the kernel's place (nothing compiles;
forty steps of an episode take about 0.1 s), and `compile_signatures` compiles them last-called first.
The two processes meet in the middle: a kernel the first one reaches after the second has saved it is
loaded from the cache, and every kernel compiles from the same source and types either way, so the
machine code is the same.

numba's cache has no lock: a process that saves a kernel writes its index before its data file, and two
processes saving different signatures of one kernel at once can give both the same data file. So
`ahead_of_time` keeps only what cannot meet either hazard: kernels of modules that had no cache file at
all when the run began (no stale data file to read in that window) and none of whose kernels was
recorded with more than one signature (kernels call only kernels of their own module, so a nested
compile stays inside such a module).
"""

from __future__ import annotations

import os
import sys
import warnings
from collections import Counter
from collections.abc import Callable, Iterable
from types import ModuleType
from typing import Any

import numpy as np

Signature = tuple[Any, tuple[Any, ...]]
"""A kernel (numba dispatcher) and the numba types of the positional arguments of one call."""


def _kernel_bindings(packages: Iterable[str] | None = None) -> list[tuple[ModuleType, str, Any]]:
    """(module, name, kernel) for every module global bound to a numba kernel in the packages' modules.

    Only modules already imported; `packages` None: every one but numba's own.
    """
    from numba.core.registry import CPUDispatcher

    roots = None if packages is None else set(packages)
    bindings = []
    for name, module in list(sys.modules.items()):
        root = name.split(".")[0]
        if module is None or (root == "numba" if roots is None else root not in roots):
            continue
        for attr, value in list(vars(module).items()):
            if isinstance(value, CPUDispatcher):
                bindings.append((module, attr, value))
    return bindings


def record_signatures(run: Callable[[], object], packages: Iterable[str] | None = None) -> list[Signature]:
    """The kernels `run` calls and their argument types, in the order of their first calls; nothing compiles.

    While `run` runs, each kernel bound to a module global of the packages' imported modules (`packages`
    None: every one but numba's own) is replaced by a stand-in that notes the numba types of its
    arguments (as the dispatcher types a call) and runs the kernel's Python function; kernels calling
    kernels reach the stand-ins through those globals too. The kernels are put back afterwards. A kernel
    reached otherwise runs compiled and is not recorded. The Python functions need not behave exactly as
    the compiled kernels (numpy warns where a kernel does not, a Python float raises on division by zero),
    so warnings are silenced and a run that fails part-way gives the signatures recorded until then: this
    only decides what compiles ahead.
    """
    from numba import typeof
    from numba.core.typing.typeof import Purpose

    recorded: dict[tuple[int, tuple[Any, ...]], Signature] = {}

    def stand_in(kernel: Any) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            if not kwargs:
                types = tuple(typeof(a, Purpose.argument) for a in args)
                recorded.setdefault((id(kernel), types), (kernel, types))
            return kernel.py_func(*args, **kwargs)

        return call

    bindings = _kernel_bindings(packages)
    stand_ins: dict[int, Callable[..., Any]] = {}
    try:
        for module, attr, kernel in bindings:
            setattr(module, attr, stand_ins.setdefault(id(kernel), stand_in(kernel)))
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            run()
    except Exception:  # see the docstring: what was recorded still compiles ahead
        pass
    finally:
        for module, attr, kernel in bindings:
            setattr(module, attr, kernel)
    return list(recorded.values())


def modules_without_cache(packages: Iterable[str] | None = None) -> set[str]:
    """The imported modules of the packages that define cached kernels and have no cache file for any yet.

    On a fresh install: every module with kernels. Read from numba's cache layout (a private part of
    numba); a kernel whose index path cannot be read makes its module count as cached (nothing ahead).
    """
    fresh: dict[str, bool] = {}
    for module, _, kernel in _kernel_bindings(packages):
        name = kernel.py_func.__module__
        if name != module.__name__:
            continue  # bound here, defined elsewhere
        try:
            absent = not os.path.exists(kernel._cache._cache_file._index_path)
        except Exception:  # not a cached kernel (numba's NullCache), or numba's layout changed
            absent = False
        fresh[name] = fresh.get(name, True) and absent
    return {name for name, absent in fresh.items() if absent}


def ahead_of_time(signatures: Iterable[Signature], fresh_modules: set[str]) -> list[Signature]:
    """The `signatures` safe to compile beside a process that compiles the same kernels.

    Those of kernels in `fresh_modules` whose module has no kernel recorded with several signatures (see
    the module docstring), in their order.
    """
    signatures = list(signatures)
    calls = Counter(id(kernel) for kernel, _ in signatures)
    several = {kernel.py_func.__module__ for kernel, _ in signatures if calls[id(kernel)] > 1}
    return [
        (kernel, types)
        for kernel, types in signatures
        if kernel.py_func.__module__ in fresh_modules and kernel.py_func.__module__ not in several
    ]


def compile_signatures(signatures: Iterable[Signature]) -> None:
    """Compile each kernel for its argument types, in the given order, into numba's on-disk cache.

    numba looks in its cache first, so a kernel another process has saved meanwhile is loaded, not compiled.
    A kernel that does not compile for the recorded types is left for the process that calls it, which
    compiles it for the types it really gets (and reports any error there, with its caller).
    """
    for kernel, types in signatures:
        try:
            kernel.compile(types)
        except Exception:  # see the docstring: nothing here is the user's error to report
            continue


def is_cached(kernel: Any) -> bool:
    """Whether numba's on-disk cache holds a compiled `kernel` (for its source file as it is now).

    Read from numba's cache index (a private part of numba); if that ever fails, the answer is True, so
    that nothing compiles ahead and the kernel compiles where it is first called, as it always may.
    """
    try:
        return bool(kernel._cache._cache_file._load_index())
    except Exception:  # not a cached kernel (numba's NullCache), or an unreadable index
        return True
