"""The pipeline's side process (optim/side.py): which evaluators go there, its results equal this
process's, a dead side process costs a recomputation (not the run), an interrupted run kills it."""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import Future

import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
from hapticopt.optim import cache as C
from hapticopt.optim import side
from hapticopt.optim.executor import InlineExecutor


def test_the_cad_fea_is_the_slow_evaluator_at_fine_fidelity_only():
    # registry: structural_stiffness adds the CAD solid FEA at fine fidelity ("tens of seconds"), and the
    # strength check that FEA's stress per part (its slow_at)
    assert side.slow_evaluators("prrr", Fidelity.FINE) == ("structural_stiffness", "strength")
    assert side.slow_evaluators("prrr", Fidelity.DRAFT) == side.slow_evaluators("prrr", Fidelity.STANDARD) == ()
    assert side.slow_evaluators("handle", Fidelity.FINE) == ()


def _pid() -> int:
    return os.getpid()


def _sleep(seconds: float) -> int:
    time.sleep(seconds)
    return os.getpid()


def test_side_evaluation_in_another_process_equals_this_ones():
    design = io.load_preset("prrr-paper")
    only = ("statics", "workspace")
    here = C.evaluate(design, Fidelity.DRAFT, cache=None, only=only)
    with side.side_executor("local") as ex:
        assert not side.in_process(ex)
        assert ex.submit(_pid).result() != os.getpid()
        there, drawn = ex.submit(side.evaluate, design, Fidelity.DRAFT, only).result()
    assert drawn == [] and there.results == {}  # no pictures asked for; result objects stay there
    for key in ("metrics", "statuses", "messages", "modules"):
        assert json.dumps(getattr(there, key)) == json.dumps(getattr(here, key)), key


def test_inline_scheduler_runs_the_side_tasks_here():
    with side.side_executor("inline") as ex:
        assert isinstance(ex, InlineExecutor) and side.in_process(ex)
        assert ex.submit(_pid).result() == os.getpid()


def test_collect_computes_here_when_the_side_process_fails():
    broken: Future = Future()
    broken.set_exception(RuntimeError("the side process died"))
    done: Future = Future()
    done.set_result("there")
    assert side.collect(done, lambda: "here") == "there"
    assert side.collect(broken, lambda: "here") == "here"
    assert side.collect(None, lambda: "here") == "here"


def test_an_interrupted_run_kills_the_side_process_without_waiting():
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt), side.side_executor("local") as ex:
        pid = ex.submit(_pid).result()
        ex.submit(_sleep, 60.0)
        time.sleep(0.2)  # the sleep has started there
        raise KeyboardInterrupt
    assert time.perf_counter() - t0 < 30.0  # the 60 s task was not waited for
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        pytest.fail(f"side process {pid} still runs")
