"""The numpy fast path of the firmware law (analysis/prrr/firmware_numpy.py) against the reference
:func:`hapticopt.analysis.prrr.firmware.step` (jax): same commands and force references tick by tick."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.prrr import closed_loop, firmware
from hapticopt.analysis.prrr.firmware_numpy import NumpyController
from hapticopt.analysis.loop.scene import BoxMode, EnvKind, FirmwareMode, load_scene, scene_names
from hapticopt.design.io import load_preset

DESIGN = load_preset("prrr-paper")


def _variants():
    out = []
    for name in sorted(scene_names()):
        if load_scene(name).controller.mode != FirmwareMode.IMPEDANCE:
            continue  # the IOIC mode has its own firmware (tests/analysis/prrr/test_firmware_ioic.py)
        st = closed_loop.setup(DESIGN, load_scene(name))
        out.append((name, st.cfg, st.gains))
    st = closed_loop.setup(DESIGN, load_scene("stiffness-25"))
    g = st.gains._replace(ki=jnp.asarray(200.0), force_amplitude=jnp.asarray([50.0, -20.0, 10.0]),
                          wall_damping=jnp.asarray(30.0), damping=jnp.asarray([100.0, 0.0, 50.0]))
    cfg = st.cfg
    out += [
        ("integral", dataclasses.replace(cfg, integral=True), g),
        ("interpolation", dataclasses.replace(cfg, interpolation=4), g),
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
    fast = NumpyController(cfg, gains)
    rng = np.random.default_rng(11)
    # a random walk of counts that crosses the box walls (10 mm = 8000 counts of 1.25 µm)
    s = np.cumsum(np.round(rng.normal(0, 400, (120, 3))), axis=0)
    dfl = np.round(rng.normal(0, 300, (120, 3)))
    ref.reset(s[0])
    fast.reset(s[0])
    for a, b in zip(s, dfl):
        np.testing.assert_allclose(fast.step(a, b), ref.step(a, b), rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(fast.last_force, ref.last_force, rtol=1e-12, atol=1e-9)
