"""Stand-in closed-loop runner for tests/optim/test_pipeline.py (runs in the pipeline's child process)."""

import time

import numpy as np

from hapticopt.analysis.loop.traces import Traces

#: the stand-in's time history: a 2 Hz, 5 mm sine along x at T = 1 ms for 1 s; the unstable scene stops at tick 600
PERIOD_S, TICKS, AMPLITUDE_M, FREQ_HZ, STOP_TICK = 1e-3, 1000, 5e-3, 2.0, 600


def traces(stop):
    t = np.arange(TICKS) * PERIOD_S
    pos = np.zeros((TICKS, 1, 3))
    pos[:, 0, 0] = AMPLITUDE_M * np.sin(2 * np.pi * FREQ_HZ * t)
    ref = np.zeros((TICKS, 1, 3))
    ref[:, 0, 0] = 25e3 * pos[:, 0, 0]  # a 25 N/mm spring
    return Traces(period=PERIOD_S, energy=np.zeros((TICKS, 1)), saturated=np.zeros((TICKS, 1), dtype=bool),
                  stop_tick=np.array([stop]), position=pos, hand_force=-0.9 * ref, actuator_force=0.95 * ref,
                  force_reference=ref, velocity=np.zeros((TICKS, 1, 3)))


class Result:
    status = "ok"
    message = ""

    def __init__(self, stable, error):
        self._m = {"stable": stable, "stiffness_error_pct": error, "rendered_stiffness_N_per_mm": 24.0}
        self.traces = traces(-1 if stable else STOP_TICK)

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
