"""The route value a caller passes down (``hapticopt.analysis.compute``): validation, thread count, the
``auto`` rule, and why a kernel cannot load."""

from __future__ import annotations

import dataclasses
import os

import pytest

from hapticopt.analysis import compute
from hapticopt.analysis.compute import DEFAULT, MAX_THREADS, Backend, Compute


def test_default_is_auto_on_every_cpu_of_the_process():
    assert DEFAULT.backend is Backend.AUTO and DEFAULT.threads is None
    assert DEFAULT.thread_count() == len(os.sched_getaffinity(0))


def test_a_backend_given_as_text_becomes_the_enum():
    assert Compute(backend="numba").backend is Backend.NUMBA
    assert Compute(backend="numpy") == Compute(backend=Backend.NUMPY)


def test_threads_is_the_thread_count_when_given():
    assert Compute(threads=1).thread_count() == 1
    assert Compute(threads=MAX_THREADS).thread_count() == MAX_THREADS


@pytest.mark.parametrize("bad", ["fast", "", "NUMPY", None])
def test_a_backend_not_allowed_is_one_line_naming_the_allowed_ones(bad):
    with pytest.raises(ValueError) as err:
        Compute(backend=bad)
    assert str(err.value) == f"backend = {bad!r} is not allowed: one of auto, numpy, numba, jax"


@pytest.mark.parametrize("bad", [0, -2, MAX_THREADS + 1, 1.5, "2", True])
def test_threads_not_allowed_is_one_line_naming_the_range(bad):
    with pytest.raises(ValueError) as err:
        Compute(threads=bad)
    assert str(err.value) == (f"threads = {bad!r} is not allowed: an integer from 1 to {MAX_THREADS}, "
                              "or None for the CPU count")


def test_compute_is_frozen_and_hashable():
    c = Compute(backend="numpy", threads=2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.threads = 3  # type: ignore[misc]
    assert {c: 1}[Compute(backend="numpy", threads=2)] == 1


@pytest.mark.parametrize(("backend", "work", "expected"), [
    ("numba", 0, True), ("numba", 10**6, True),  # always
    ("numpy", 0, False), ("numpy", 10**6, False),  # never
    ("auto", 99, False), ("auto", 100, True),  # from the threshold on (threshold 100 below)
    ("jax", 99, False), ("jax", 100, True),  # jax has no numba route to replace: as auto
])
def test_use_numba_follows_the_backend_and_the_size_of_the_work(backend, work, expected):
    assert Compute(backend=backend).use_numba(work, 100) is expected


def test_use_numba_does_not_depend_on_earlier_calls():
    c = Compute()
    answers = [c.use_numba(n, 100) for n in (10, 1000, 10, 1000, 10)]
    assert answers == [False, True, False, True, False]


def test_unavailable_is_none_when_the_kernel_loads_and_names_what_failed_otherwise():
    assert compute.unavailable(lambda: None, "the kernel") is None

    def load() -> None:
        raise OSError("no cache folder is writable")

    assert compute.unavailable(load, "the kernel") == "the kernel did not load: no cache folder is writable"
