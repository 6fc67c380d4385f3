"""The firmware law (analysis/prrr/loop/firmware_law.py) is written once and instantiated three times: on Python
floats (ScalarController, the Python MuJoCo loop), compiled by numba (the MuJoCo tick kernel) and on jax arrays
(firmware.step, the lumped plant's batched loop). The three give the same commands and force references tick by
tick on every bundled scene's structure and on the optional terms the scenes do not reach."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.prrr.loop import closed_loop, firmware, firmware_law
from hapticopt.analysis.prrr.loop.firmware import ScalarController, controller
from hapticopt.analysis.loop.scene import BoxMode, EnvKind, FirmwareMode, load_scene, scene_names
from hapticopt.design.io import load_preset

DESIGN = load_preset("prrr-paper")


def _variants():
    out = []
    for name in sorted(scene_names()):
        if load_scene(name).controller.mode != FirmwareMode.IMPEDANCE:
            continue  # the IOIC mode has its own firmware (tests/analysis/prrr/loop/test_firmware_ioic.py)
        st = closed_loop.setup(DESIGN, load_scene(name))
        if st.cfg.interpolation == 1:
            out.append((name, st.cfg, st.gains))
    st = closed_loop.setup(DESIGN, load_scene("stiffness-25"))
    g = st.gains._replace(ki=jnp.asarray(200.0), force_amplitude=jnp.asarray([50.0, -20.0, 10.0]),
                          wall_damping=jnp.asarray(30.0), damping=jnp.asarray([100.0, 0.0, 50.0]))
    cfg = st.cfg
    out += [
        ("integral", dataclasses.replace(cfg, integral=True), g),
        ("box-outside", dataclasses.replace(cfg, env=EnvKind.BOX, box_mode=BoxMode.OUTSIDE), g),
        ("box-inside", dataclasses.replace(cfg, env=EnvKind.BOX, box_mode=BoxMode.INSIDE), g),
        ("force", dataclasses.replace(cfg, env=EnvKind.FORCE), g),
        ("free-comp", dataclasses.replace(cfg, env=EnvKind.FREE, friction_compensation=True,
                                          gravity_compensation=True, velocity_alpha=0.5), g),
        ("rigid", dataclasses.replace(cfg, force_loop=firmware.ForceLoop.RIGID), g),
        ("ideal", dataclasses.replace(cfg, force_loop=firmware.ForceLoop.IDEAL, saturation=False), g),
    ]
    return out


VARIANTS = _variants()
#: agreement of the jax instantiation with the Python one, relative to the largest term (a few float64 ulps)
RTOL = 1e-15


def _counts(seed: int, n: int):
    """A random walk of slider counts that crosses the box walls (10 mm = 8000 counts of 1.25 µm) and random
    spring-deflection counts."""
    rng = np.random.default_rng(seed)
    return np.cumsum(np.round(rng.normal(0, 400, (n, 3))), axis=0), np.round(rng.normal(0, 300, (n, 3)))


@pytest.mark.parametrize("name,cfg,gains", VARIANTS, ids=lambda x: x if isinstance(x, str) else "")
def test_python_and_jax_instantiations_agree(name, cfg, gains):
    """Equal to RTOL of the terms' scale: XLA contracts a·b + c into one fused multiply-add (one rounding where
    Python and numba round twice), so the two differ in the last bits of p = J r c, and the law carries that
    difference on: into ṗ̂ divided by T, into the friction compensation's tanh divided by T·v_ε as well. The
    scale of F_r is therefore |F_r| plus (F_fc/v_ε + B_v + B_wall)·|p|/T, that of the commands
    max(K_p, 1/η, 1)·(3 |J| · F_r's scale + k r |dc|) (bounds over the run)."""
    jax_ctl, py = firmware.FirmwareController(cfg, gains), ScalarController(cfg, gains)
    s, dfl = _counts(11, 120)
    jax_ctl.reset(s[0])
    py.reset(s[0])
    got = [(py.step(a, b)[0], py.last_force, jax_ctl.step(a, b)[0], jax_ctl.last_force) for a, b in zip(s, dfl)]
    cmd_py, F_py, cmd_jax, F_jax = (np.array(x) for x in zip(*got))
    g = {k: float(np.max(np.abs(v))) for k, v in gains._asdict().items() if v is not None}
    p_max = np.abs(s @ np.asarray(gains.J).T * g["resolution"]).max()
    damping = g["friction_comp"] / g["friction_comp_velocity"] * cfg.friction_compensation + g["damping"]
    F_scale = np.abs(F_py).max() + (damping + g["wall_damping"]) * p_max / cfg.period
    cmd_scale = max(g["kp"], 1.0 / g["efficiency"], 1.0) * (3 * g["J"] * F_scale
                                                            + g["spring"] * g["resolution"] * np.abs(dfl).max())
    np.testing.assert_allclose(F_jax, F_py, rtol=0, atol=RTOL * F_scale)
    np.testing.assert_allclose(cmd_jax, cmd_py, rtol=0, atol=RTOL * cmd_scale)


def test_the_compiled_law_is_the_python_law_bit_for_bit():
    """The kernel's instantiation (numba), as the compiled MuJoCo loop calls it, gives the Python call's bits on
    every variant (the MuJoCo scenes reach only some branches: box outside and the force reference are here)."""
    from numba import njit

    from hapticopt.analysis.prrr.loop._mujoco_kernel import LAW

    tick = LAW.tick

    @njit
    def run(par, flg, J, K, B, anchor, half, famp, fphase, st, k, sc, dc):
        p, v, ig, F, o = tick(par, flg, J, K, B, anchor, half, famp, fphase, (st[0], st[1], st[2]),
                                  (st[3], st[4], st[5]), (st[6], st[7], st[8]), k, sc, dc)
        return np.array([*p, *v, *ig, *F]), np.array([*o])

    for name, cfg, gains in VARIANTS:
        py = ScalarController(cfg, gains)
        args = [np.array(a, dtype=np.int64 if i == 1 else np.float64) for i, a in enumerate(py.args)]
        s, dfl = _counts(3, 80)
        py.reset(s[0])
        st = np.array(py.state)
        for k, (a, b) in enumerate(zip(s, dfl)):
            want = py.step(a.tolist(), b.tolist())[0]
            st, out = run(*args, st, k, a, b)
            assert out.tobytes() == want.tobytes() and st.tobytes() == np.array(py.state).tobytes(), name


def test_the_jax_ar_fit_is_the_shared_fit_per_axis():
    # firmware.fit_ar_axes (jax, SVD) against analysis.control.upsampling.fit_ar (numpy lstsq), axis by axis:
    # a random walk (fits), a constant axis (unexciting: fallback (2, −1)), and a damped sinusoid whose AR(2)
    # coefficients are 2e^{−σT}cos ωT and −e^{−2σT} (closed form)
    from hapticopt.analysis.control import upsampling as up
    rng = np.random.default_rng(5)
    T, k = 1e-3, np.arange(16)
    pos = np.stack([np.cumsum(rng.normal(size=16)) * 1e-4, np.full(16, 3e-3),
                    1e-3 * np.exp(-3.0 * k * T) * np.cos(70.0 * k * T)], axis=1)
    coef, ok = firmware.fit_ar_axes(jnp.asarray(pos), 2)
    for ax in range(3):
        ref = up.fit_ar(pos[:, ax], order=2, window=16)
        np.testing.assert_allclose(np.asarray(coef[ax]), ref.coefficients, rtol=1e-9)
        assert bool(ok[ax]) == (ref.status is up.ARStatus.FITTED)
    assert not bool(ok[1]) and np.allclose(coef[1], (2.0, -1.0))
    np.testing.assert_allclose(coef[2], (2.0 * np.exp(-3.0 * T) * np.cos(70.0 * T), -np.exp(-6.0 * T)), rtol=1e-6)


def test_interpolation_is_the_jax_steps():
    cfg = dataclasses.replace(closed_loop.setup(DESIGN, load_scene("stiffness-25")).cfg, interpolation=4)
    gains = closed_loop.setup(DESIGN, load_scene("stiffness-25")).gains
    assert isinstance(controller(cfg, gains), firmware.FirmwareController)
    with pytest.raises(ValueError, match="interpolation 1"):
        ScalarController(cfg, gains)


def test_the_law_is_written_once():
    """Only firmware_law.py spells the rendered force and the force loop: the jax step, the scalar controller and
    the MuJoCo kernel call it (none has a wall, a compensation or a force-loop gain of its own), and the removed copies do not
    come back."""
    root = Path(firmware_law.__file__).resolve().parents[1]  # analysis/prrr/
    for mod in ("firmware.py", "_mujoco_kernel.py"):
        text = (root / "loop" / mod).read_text()
        assert not re.search(r"depth|wall_stiffness \*|friction_comp \*|kp\[|ki\[|weight \*", text), mod
    assert "make_law(" in (root / "loop" / "_mujoco_kernel.py").read_text()
    for path in root.parents[0].rglob("*.py"):
        text = path.read_text()
        for name in ("step_generic", "_step_scalar", "NumpyController", "def _render", "def _force_loop"):
            assert name not in text, f"{name} in {path}"
