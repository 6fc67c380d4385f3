"""The scalar firmware law (analysis/prrr/loop/firmware_law.py, the MuJoCo loops' one definition) against the jax law
:func:`hapticopt.analysis.prrr.loop.firmware.step` (the lumped plant's): same commands and force references tick by tick."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.prrr.loop import closed_loop, firmware, firmware_law as firmware_numpy
from hapticopt.analysis.prrr.loop.firmware_law import ScalarController, controller
from hapticopt.analysis.loop.scene import BoxMode, EnvKind, FirmwareMode, load_scene, scene_names
from hapticopt.design.io import load_preset

DESIGN = load_preset("prrr-paper")


def _variants():
    out = []
    for name in sorted(scene_names()):
        if load_scene(name).controller.mode != FirmwareMode.IMPEDANCE:
            continue  # the IOIC mode has its own firmware (tests/analysis/prrr/loop/test_firmware_ioic.py)
        st = closed_loop.setup(DESIGN, load_scene(name))
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
    ]
    return out


@pytest.mark.parametrize("name,cfg,gains", _variants(), ids=lambda x: x if isinstance(x, str) else "")
def test_numpy_law_equals_reference(name, cfg, gains):
    ref = firmware.FirmwareController(cfg, gains)
    fast = ScalarController(cfg, gains)
    rng = np.random.default_rng(11)
    # a random walk of counts that crosses the box walls (10 mm = 8000 counts of 1.25 µm)
    s = np.cumsum(np.round(rng.normal(0, 400, (120, 3))), axis=0)
    dfl = np.round(rng.normal(0, 300, (120, 3)))
    ref.reset(s[0])
    fast.reset(s[0])
    for a, b in zip(s, dfl):
        np.testing.assert_allclose(fast.step(a, b), ref.step(a, b), rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(fast.last_force, ref.last_force, rtol=1e-12, atol=1e-9)


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


def test_interpolation_is_the_jax_laws():
    cfg = dataclasses.replace(closed_loop.setup(DESIGN, load_scene("stiffness-25")).cfg, interpolation=4)
    gains = closed_loop.setup(DESIGN, load_scene("stiffness-25")).gains
    assert isinstance(controller(cfg, gains), firmware.FirmwareController)
    with pytest.raises(ValueError, match="interpolation 1"):
        ScalarController(cfg, gains)


def test_the_scalar_law_is_written_once():
    """The MuJoCo loops' law is firmware_numpy.tick alone: the compiled loop calls it (no inlined copy: no
    tanh/sin of its own) and the removed second paths do not come back."""
    root = Path(firmware_numpy.__file__).resolve().parents[1]  # analysis/
    kernel = (root / "prrr" / "_mujoco_kernel.py").read_text()
    assert "_law(" in kernel and "tanh" not in kernel and "math.sin" not in kernel
    for path in root.rglob("*.py"):
        text = path.read_text()
        for name in ("step_generic", "_step_scalar", "NumpyController"):
            assert name not in text, f"{name} in {path}"


def test_the_compiled_law_is_the_python_law_bit_for_bit():
    """numba.njit(tick), as the compiled MuJoCo loop runs it, gives the Python call's bits on every variant
    (the MuJoCo scenes reach only some branches: box outside and the force reference are checked here)."""
    import numba

    law = numba.njit(firmware_numpy.tick)
    rng = np.random.default_rng(3)
    for name, cfg, gains in _variants():
        py = ScalarController(cfg, gains)
        args = [np.array(a, dtype=np.int64 if i == 1 else np.float64) for i, a in enumerate(py.args)]
        s = np.cumsum(np.round(rng.normal(0, 400, (80, 3))), axis=0)
        dfl = np.round(rng.normal(0, 300, (80, 3)))
        py.reset(s[0])
        st, out = np.array(py.state), np.empty(3)
        for k, (a, b) in enumerate(zip(s, dfl)):
            want = py.step(a.tolist(), b.tolist())[0]
            law(*args, st, k, a, b, out)
            assert out.tobytes() == want.tobytes() and st.tobytes() == np.array(py.state).tobytes(), name

