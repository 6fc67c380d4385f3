"""The watcher kills a run's process tree when the run is SIGKILLed (issue 14: pool workers, the
resource tracker and the verification child outlived a SIGKILL of the parent by ≥ 30 s)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

CODE = r"""
import subprocess, sys, time
from hapticopt.optim.reaper import children_die_with_this_process
with children_die_with_this_process():
    # a child and a grandchild that never look at their parent (like a worker still importing)
    c = subprocess.Popen([sys.executable, "-c",
                          "import subprocess, sys, time; g = subprocess.Popen([sys.executable, '-c', "
                          "'import time; time.sleep(60)']); print(g.pid, flush=True); time.sleep(60)"],
                         stdout=subprocess.PIPE, text=True)
    print(c.pid, c.stdout.readline().strip(), flush=True)
    time.sleep(60)
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in "ZX"
    except OSError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="the watcher reads /proc (Linux)")
def test_descendants_die_within_a_second_of_a_sigkill():
    p = subprocess.Popen([sys.executable, "-c", CODE], stdout=subprocess.PIPE, text=True)
    kids = [int(x) for x in p.stdout.readline().split()]
    time.sleep(0.6)  # the watcher has recorded the tree (every 0.2 s)
    assert all(_alive(k) for k in kids)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    p.stdout.close()
    t0 = time.monotonic()
    while any(_alive(k) for k in kids) and time.monotonic() - t0 < 5:
        time.sleep(0.02)
    assert not any(_alive(k) for k in kids) and time.monotonic() - t0 < 1.0


def test_a_normal_exit_stops_the_watcher():
    from hapticopt.optim.reaper import children_die_with_this_process

    with children_die_with_this_process() as watcher:
        assert watcher is None or watcher.poll() is None
    assert watcher is None or watcher.poll() is not None
