"""Calls for tests/optim/test_worker.py (module-level: they run in the worker process)."""

import os
import signal
import time


def pid_and(x):
    return os.getpid(), x


def segfault():
    os.kill(os.getpid(), signal.SIGSEGV)
    time.sleep(10)


def hang():
    time.sleep(60)


def raises():
    raise ValueError("scene x: bad value")


def exits():
    os._exit(3)


def slow_warm():
    time.sleep(1.0)
