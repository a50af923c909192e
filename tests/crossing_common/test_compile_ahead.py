"""Compiling kernels ahead: the recorded signatures are the ones a compiled run uses, and nothing compiles
while they are recorded; on a fresh install the warm-up's child compiles kernels the warm-up then loads."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from crossing_common import compile_ahead

RECORD_ON_AN_EMPTY_CACHE = """
import rollout
from crossing_common import compile_ahead
from crossing_env.pedestrians import social_force
from crossing_eval.tasks import build_policy, cached_env

env, _ = cached_env("zebra_case1")


def steps():
    rollout.run_episode(env, 5, policy=build_policy("yielding", env), max_steps=20)


kernel = social_force.walk_step
assert not compile_ahead.is_cached(kernel), "an empty cache reads as holding the kernel"
fresh = compile_ahead.modules_without_cache()
assert {"crossing_env.pedestrians.social_force", "agents.view"} <= fresh, fresh
bindings = [(m.__name__, name, id(k)) for m, name, k in compile_ahead._kernel_bindings()]
signatures = compile_ahead.record_signatures(steps)
kernels = {id(k): k for _, _, k in compile_ahead._kernel_bindings()}
assert [(m.__name__, name, id(k)) for m, name, k in compile_ahead._kernel_bindings()] == bindings, (
    "a kernel was not put back where it was bound"
)
assert not [k.__name__ for k in kernels.values() if k.signatures], "recording compiled a kernel"
names = {k.py_func.__module__ + "." + k.__name__ for k, _ in signatures}
expected = {
    "crossing_env.pedestrians.social_force.walk_step",
    "crossing_env.observation._fill_pedestrian_slots",
}
assert expected <= names, names
assert any(name.startswith("agents.") for name in names), "the policy's kernels are not recorded"

ahead = compile_ahead.ahead_of_time(signatures, fresh)
assert ahead == signatures, "a kernel of the env or the policy is not compiled ahead (several signatures?)"
compile_ahead.compile_signatures(reversed(ahead))
assert compile_ahead.is_cached(kernel), "a compiled kernel is not in the cache"
assert "crossing_env.pedestrians.social_force" not in compile_ahead.modules_without_cache()
before = {i: list(k.signatures) for i, k in kernels.items()}
steps()
after = {i: list(k.signatures) for i, k in kernels.items()}
new = [kernels[i].__name__ for i in before if before[i] != after[i]]
assert not new, f"the compiled run needed argument types the recording did not see: {new}"
"""

WARM_UP_ON_AN_EMPTY_CACHE = """
from crossing_common import compile_ahead
from crossing_eval import tasks
from crossing_env.pedestrians import social_force

task = tasks.make_tasks(["zebra_case1"], ["always_cautious"], 1, 3)[0]
assert not social_force.walk_step.stats.cache_hits
tasks.warm_up(task)
hits = [k.__name__ for _, _, k in compile_ahead._kernel_bindings(["crossing_env", "agents"])
        if sum(k.stats.cache_hits.values())]
assert hits, "the warm-up loaded no kernel its child compiled"
"""


@pytest.mark.slow
def test_recorded_signatures_are_those_a_compiled_run_uses(
    run_with_empty_numba_cache: Callable[[str], None],
) -> None:
    run_with_empty_numba_cache(RECORD_ON_AN_EMPTY_CACHE)


@pytest.mark.slow
def test_on_a_fresh_install_the_warm_up_loads_kernels_its_child_compiled(
    run_with_empty_numba_cache: Callable[[str], None],
) -> None:
    """The child compiles the last-called kernels first: the warm-up reaches them last and loads them.

    It starts on them at once (a plain policy offers no predictor kernel), while this process has all the
    others to compile before it reaches the last.
    """
    run_with_empty_numba_cache(WARM_UP_ON_AN_EMPTY_CACHE)


def test_a_run_that_fails_part_way_gives_what_it_recorded_and_puts_the_kernels_back() -> None:
    from agents import view

    kernel = view._nan_max

    def run() -> None:
        assert view._nan_max is not kernel, "the kernel was not replaced while recording"
        assert view._nan_max(1.0, 2.0) == 2.0  # the kernel's Python function
        view._nan_max(1.0, 2.0)  # a second call records nothing new
        raise RuntimeError("a Python function that fails where its kernel does not")

    signatures = compile_ahead.record_signatures(run, ["agents"])
    assert view._nan_max is kernel
    assert [(k, tuple(str(t) for t in types)) for k, types in signatures] == [
        (kernel, ("float64", "float64")),
        (view._numpy_pick, ("float64", "float64", "bool")),  # called by the kernel's Python function
    ]


def test_a_kernel_that_does_not_compile_for_recorded_types_is_left_and_the_rest_compile() -> None:
    from numba import njit, types

    @njit
    def add_one(x: int) -> int:  # a kernel of this test, not cached
        return x + 1

    compile_ahead.compile_signatures([(add_one, (types.unicode_type,)), (add_one, (types.int64,))])
    assert add_one.signatures == [(types.int64,)]


def test_only_fresh_modules_whose_kernels_have_one_signature_compile_ahead() -> None:
    """Two processes saving different signatures of one kernel at once can share a data file in numba's
    cache, and a module with cache files may hold stale ones: neither is compiled ahead."""
    from numba import types

    from agents import view
    from crossing_env.pedestrians import social_force

    one = (social_force.walk_step, (types.float64,))
    several = [(view._nan_max, (types.float64, types.float64)), (view._nan_max, (types.int64, types.int64))]
    other_of_that_module = (view._stop_kernel, (types.float64,))
    fresh = {"agents.view", "crossing_env.pedestrians.social_force"}
    assert compile_ahead.ahead_of_time([*several, one, other_of_that_module], fresh) == [one]
    assert compile_ahead.ahead_of_time([one, other_of_that_module], {"agents.view"}) == [other_of_that_module]


def test_a_kernel_without_a_readable_cache_index_reads_as_cached() -> None:
    """So that nothing compiles ahead where numba's private cache layout has changed."""
    assert compile_ahead.is_cached(object())
