"""hapticopt.optim.worker: one long-lived process, each call under a time limit; a call that hangs or
kills the process is a value (timeout / crashed), never an exception in the parent, and the next call
gets a fresh process (issue 22: the verify stage's crash safety with one process instead of one per scene)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from hapticopt.optim.worker import SupervisedWorker, describe_exit

DATA = Path(__file__).parent / "data"


@pytest.fixture
def tasks(monkeypatch):
    monkeypatch.syspath_prepend(str(DATA))  # the worker (spawned) imports the tasks module too
    monkeypatch.setenv("PYTHONPATH", str(DATA))
    import worker_tasks

    return worker_tasks


def test_calls_share_one_process(tasks):
    with SupervisedWorker() as w:
        outs = [w.call(tasks.pid_and, (i,), timeout_s=30) for i in range(3)]
    assert [o.kind for o in outs] == ["ok"] * 3
    assert [o.value[1] for o in outs] == [0, 1, 2]
    assert len({o.value[0] for o in outs}) == 1 and w.starts == 1


def test_segfault_hang_and_exception_are_values_and_the_next_call_runs(tasks):
    with SupervisedWorker() as w:
        first = w.call(tasks.pid_and, ("a",), timeout_s=30)
        seg = w.call(tasks.segfault, (), timeout_s=30)
        after_seg = w.call(tasks.pid_and, ("b",), timeout_s=30)
        t0 = time.perf_counter()
        hung = w.call(tasks.hang, (), timeout_s=1.0)
        waited = time.perf_counter() - t0
        after_hang = w.call(tasks.pid_and, ("c",), timeout_s=30)
        err = w.call(tasks.raises, (), timeout_s=30)
        after_err = w.call(tasks.pid_and, ("d",), timeout_s=30)
        ex = w.call(tasks.exits, (), timeout_s=30)
    assert (seg.kind, seg.message) == ("crashed", "the worker process died (killed by SIGSEGV)")
    assert after_seg.kind == "ok" and after_seg.value[0] != first.value[0]  # a fresh process
    assert hung.kind == "timeout" and 1.0 <= waited < 10.0
    assert after_hang.kind == "ok" and after_hang.value[0] != after_seg.value[0]
    assert (err.kind, err.message) == ("error", "ValueError: scene x: bad value")
    assert after_err.value[0] == after_hang.value[0]  # an exception does not cost the process
    assert (ex.kind, ex.message) == ("crashed", "the worker process died (exit code 3)")
    assert w.starts == 3


def test_close_leaves_no_process(tasks):
    w = SupervisedWorker().start()
    pid = w.call(tasks.pid_and, (1,), timeout_s=30).value[0]
    w.close()
    assert w.last_exitcode == 0  # asked to finish, finished (not killed)
    assert not Path(f"/proc/{pid}").exists()


def test_describe_exit():
    assert describe_exit(-9) == "killed by SIGKILL"
    assert describe_exit(0) == "exit code 0"
    assert describe_exit(None) == "no exit code"


def test_time_limit_starts_once_the_process_is_ready(tasks):
    """Start-up (imports, ``warm``) is not charged to a call: a 1 s warm-up, then a 0.5 s limit, still answers."""
    with SupervisedWorker(warm=tasks.slow_warm) as w:
        out = w.call(tasks.pid_and, (1,), timeout_s=0.5)
    assert out.kind == "ok"


def test_start_up_that_dies_is_reported(tasks):
    with SupervisedWorker(warm=tasks.exits) as w:
        out = w.call(tasks.pid_and, (1,), timeout_s=5)
    assert (out.kind, out.message) == ("crashed", "the worker process died (exit code 3) during its start-up")
