"""Stand-in closed-loop runner for tests/optim/test_pipeline.py (runs in the pipeline's child process)."""

import time


class Result:
    status = "ok"
    message = ""

    def __init__(self, stable, error):
        self._m = {"stable": stable, "stiffness_error_pct": error, "rendered_stiffness_N_per_mm": 24.0}

    def metrics(self):
        return self._m


def run_scene(design, scene):
    if scene == "hangs":
        time.sleep(60)
    if scene == "slow-scene":  # a verification that takes a while: a window to kill the pipeline in
        time.sleep(1.0)
    return Result(scene != "unstable-scene", 25.0 if scene == "soft-scene" else 4.0)


def crashes(design, scene):
    """A scene whose simulation kills its process (a segfault in a native library)."""
    import os
    import signal

    if scene == "segfaults":
        os.kill(os.getpid(), signal.SIGSEGV)
    return run_scene(design, scene)
