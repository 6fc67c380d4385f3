"""Executors: inline, local process pool and a Dask cluster on loopback give the same results."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hapticopt.design.errors import InvalidInput
from hapticopt.optim import driver
from hapticopt.analysis.compute import Compute
from hapticopt.optim.executor import InlineExecutor, make_executor, worker_compute, worker_count
from hapticopt.optim.problem import load_problem

ONLY = ("statics",)  # the problem's metrics all come from hapticopt.analysis.prrr.structure.statics
PROBLEM = Path(__file__).parent / "data" / "resume-problem.toml"


def _square(x):
    return x * x


def _boom():
    raise ValueError("boom")


def test_inline_executor_is_an_executor():
    ex = InlineExecutor()
    assert ex.submit(_square, 3).result() == 9
    assert list(ex.map(_square, [1, 2, 3])) == [1, 4, 9]
    with pytest.raises(ValueError, match="boom"):
        ex.submit(_boom).result()
    assert worker_count(ex) == 1


def test_unknown_scheduler_is_one_line_error():
    with pytest.raises(InvalidInput, match="use local, inline or a Dask address"):
        with make_executor("cluster-please"):
            pass


def _by_start(res):
    """Each start's own sequence (starts run concurrently on a parallel executor)."""
    return {s.start: [(r.x, r.f) for r in res.history if r.start == s.start] for s in res.starts}


def test_same_results_inline_process_pool_and_dask_loopback():
    from distributed import LocalCluster

    problem = load_problem(PROBLEM)
    inline = driver.run(problem, only=ONLY)
    with make_executor("local", workers=2) as pool:
        assert worker_count(pool) == 2
        pooled = driver.run(problem, only=ONLY, executor=pool)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        with make_executor(cluster.scheduler_address) as dask_ex:
            assert worker_count(dask_ex) == 2
            dasked = driver.run(problem, only=ONLY, executor=dask_ex)
    assert _by_start(pooled) == _by_start(inline) == _by_start(dasked)
    assert pooled.best.x == inline.best.x == dasked.best.x
    assert pooled.n_evaluated == inline.n_evaluated == dasked.n_evaluated


def _run_python(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)


_ENDS = """
import atexit, sys
from hapticopt.optim.executor import skip_teardown_at_exit
skip_teardown_at_exit(lambda: {status})
atexit.register(lambda: print("later handler ran"))  # registered after: runs before the end
print("unflushed", end="")
sys.stdout.write("")
{exit}
"""


@pytest.mark.parametrize(("status", "exit_", "code"), [("3", "", 3), ("0", "raise SystemExit(5)", 0),
                                                       ("None", "raise SystemExit(5)", 5)])
def test_skip_teardown_ends_with_the_status_after_the_other_handlers(status, exit_, code):
    # the process ends with status() (None: as the interpreter would), output flushed, later handlers run
    done = _run_python(_ENDS.format(status=status, exit=exit_))
    assert done.returncode == code
    assert done.stdout == "unflushedlater handler ran\n"


def test_cli_main_ends_with_the_command_status():
    # a bad preset is exit 2 (optim/cli/common.py EXIT_CODES_HELP); --help is 0
    bad = _run_python("from hapticopt.optim.cli import main; import sys; "
                      "sys.argv = ['hapticopt', 'evaluate', '--preset', 'no-such-preset']; main()")
    assert bad.returncode == 2 and "no-such-preset" in bad.stderr
    ok = _run_python("from hapticopt.optim.cli import main; import sys; sys.argv = ['hapticopt', '--help']; main()")
    assert ok.returncode == 0 and "Usage" in ok.stdout


@pytest.mark.parametrize("backend", ["auto", "numpy", "numba", "jax"])
def test_work_in_a_pool_gets_one_kernel_thread_and_the_callers_backend(backend):
    """A pool's workers share the CPUs: the work submitted there is handed one kernel thread, the caller's
    backend; work run inline keeps the caller's Compute (``worker_compute``)."""
    mine = Compute(backend=backend, threads=2)
    assert worker_compute(InlineExecutor(), mine) is mine
    with make_executor("local", workers=1) as pool:  # no worker starts before a submit
        assert worker_compute(pool, mine) == Compute(backend=backend, threads=1)
