"""Foundation benchmarks (issue 2): IK of 10⁶ points after jit, jit compile time, CLI end to end.

Targets: IK with all joint angles and reachability for 10⁶ points ≤ 0.5 s after jit (2-core CPU);
`hapticopt evaluate --preset prrr-paper` process start to exit ≤ 3 s.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design.prrr import kinematics as kin
from hapticopt.design import io

N = 1_000_000


def _ik_all(params, p):
    sol = kin.inverse_kinematics(params, p)
    return sol.sliders, sol.theta, sol.reachable


def test_ik_million_points(benchmark):
    params = kin.params_of(io.load_preset("prrr-paper"))
    rng = np.random.default_rng(0)
    p = jnp.asarray(rng.uniform(-0.08, 0.08, size=(N, 3)))
    f = jax.jit(_ik_all)
    t0 = time.perf_counter()
    jax.block_until_ready(f(params, p))
    compile_s = time.perf_counter() - t0
    benchmark.extra_info["jit_compile_plus_first_run_s"] = compile_s
    benchmark.pedantic(lambda: jax.block_until_ready(f(params, p)), rounds=5, iterations=1)


def test_cli_evaluate_end_to_end(benchmark):
    exe = str(Path(sys.executable).with_name("hapticopt"))

    def run():
        subprocess.run([exe, "evaluate", "--preset", "prrr-paper", "--json"], check=True, capture_output=True)

    benchmark.pedantic(run, rounds=5, iterations=1)
