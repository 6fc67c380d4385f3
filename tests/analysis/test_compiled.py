"""The kernel thread setting (``hapticopt.analysis.compiled.threads``)."""

from __future__ import annotations

import os

import pytest

from hapticopt.analysis import compiled


def test_threads_default_is_the_cpus_this_process_may_use_and_can_be_set():
    compiled.set_threads(None)
    try:
        assert compiled.threads() == len(os.sched_getaffinity(0))
        compiled.set_threads(1)
        assert compiled.threads() == 1
    finally:
        compiled.set_threads(None)


@pytest.mark.parametrize("bad", [0, -2, 1.5, "2"])
def test_threads_rejects_what_is_not_a_positive_integer(bad):
    with pytest.raises(ValueError, match="threads"):
        compiled.set_threads(bad)
