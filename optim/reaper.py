"""Children die with the parent: a small watcher process that kills the run's process tree when
the run's process is gone, however it went (``SIGKILL`` included).

Pool workers and the verification child also watch their parent themselves
(:func:`hapticopt.optim.executor.watch_parent`), but only once their imports are done — seconds
after they start on a loaded machine. The watcher covers that window: a bare Python (``-I -S``,
no imports beyond ``os``/``time``/``signal``) started first, which records the run's descendants
from ``/proc`` every :data:`PERIOD_S` and, when the run's process has exited, sends ``SIGKILL`` to
every recorded descendant that still runs (matched by pid *and* start time, so a reused pid is
never hit). Linux only (``/proc``); elsewhere it is not started.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator

#: how often the watcher records the process tree [s]
PERIOD_S = 0.2

_WATCHER = r"""
import os, signal, sys, time
root, period, me = int(sys.argv[1]), float(sys.argv[2]), os.getpid()
def table():
    out = {}
    for e in os.listdir('/proc'):
        if e.isdigit():
            try:
                with open('/proc/%s/stat' % e) as fh:
                    f = fh.read().rsplit(')', 1)[1].split()
            except OSError:
                continue
            out[int(e)] = (int(f[1]), f[19], f[0])  # ppid, start time, state
    return out
known = {}
while True:
    t = table()
    if root not in t or t[root][2] in 'ZX':
        break
    kids, todo = set(), [root]
    while todo:
        p = todo.pop()
        for c, (pp, st, s) in t.items():
            if pp == p and c not in kids and c != me:
                kids.add(c); todo.append(c)
    for c in kids:
        known[c] = t[c][1]
    time.sleep(period)
t = table()
for c, st in known.items():
    if c in t and t[c][1] == st and t[c][2] not in 'ZX':
        try:
            os.kill(c, signal.SIGKILL)
        except OSError:
            pass
"""


@contextlib.contextmanager
def children_die_with_this_process() -> Iterator[subprocess.Popen | None]:
    """Run the body with a watcher that kills this process's descendants if this process dies."""
    if not os.path.isdir("/proc/self"):
        yield None
        return
    watcher = subprocess.Popen([sys.executable, "-I", "-S", "-c", _WATCHER, str(os.getpid()), str(PERIOD_S)],
                               stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               close_fds=True)
    try:
        yield watcher
    finally:
        watcher.kill()
        watcher.wait()
