"""The closed loops of the MuJoCo plants compiled: firmware law and ``mj_step`` in one native loop.

The plants' Python loops (``hapticopt.analysis.prrr.loop.mujoco_plant.MujocoPlant.run``,
``hapticopt.analysis.master.mujoco_plant.MasterPlant.run``) call ``mj_step(model, data, nstep=k)``
once per firmware tick with the command held; the Python firmware and the per-tick bookkeeping
between the calls cost more than the physics. Here the same tick loop runs in numba
(``@njit(cache=True)``; the 3-PRRR's in :mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`): the encoder read, the
firmware law (the 3-PRRR's is the Python loop's own function compiled; the master's term by term and in the
order of its Python controller: the traces are bit-identical; the master's dynamics compensation, whose reference
differences M̂ numerically, in closed form — M̂ in a 13-function trig basis of (θ2, θ3) identified once per plant and model —
within the reference's rounding envelope), the delay line, the hand reference, the
``mj_step`` calls and the per-tick records into preallocated arrays. Python runs once per chunk
of ticks (the plants' instability checks stay vectorised numpy between chunks).

Native access:

* ``mj_step`` is called by name (:func:`llvmlite.binding.load_library_permanently` on the
  ``libmujoco`` the ``mujoco`` bindings ship and load, so model and data structs match), which
  keeps the compiled code cacheable (a ctypes function pointer would be a "dynamic global").
* mjData's fixed arrays (qpos, qvel, qacc, ctrl, qfrc_applied, energy, site_xpos) are numpy views
  from the bindings (MuJoCo does not move them). The variable-size constraint arrays (efc_pos,
  efc_force, efc_type, efc_id) are re-allocated in mjData's arena by every step, so their pointers
  and the sizes ne / nefc are read from the mjData struct after each step at offsets found once per
  process by :func:`layout` and checked on a probe model (two states with different ne / nefc);
  a layout that does not check out makes :func:`availability` report why and the plants run the
  Python loop (unless the caller's ``Compute`` forces numba: then they raise).

A MuJoCo *error* (``mju_error``, e.g. arena overflow) inside the compiled loop goes to MuJoCo's
default handler (message, process exit) instead of ``mujoco.FatalError``; the plants' fixed models
do not raise any (their arena is sized at model compile). Warnings (BADQACC …) behave as through
the bindings (counted in ``MjData.warning``, printed by MuJoCo).

numba's on-disk cache (``cache=True``) is written next to this file's ``__pycache__``; where that is
read-only numba itself falls back to the user's cache folder (``~/.cache/numba``) or
``NUMBA_CACHE_DIR`` when set.
"""

from __future__ import annotations

import ctypes
import functools
import os
from dataclasses import dataclass


from hapticopt.analysis.compute import unavailable
from hapticopt.analysis.loop.scene import Backend, load_scene, resolve
from hapticopt.design.errors import InvalidInput


@dataclass(frozen=True)
class Layout:
    """Byte offsets in mjData of the fields the compiled loops read after each step."""

    time: int
    ne: int
    nefc: int
    efc_pos: int
    efc_force: int
    efc_type: int
    efc_id: int


def _libmujoco_path() -> str:
    import mujoco

    d = os.path.dirname(mujoco.__file__)
    names = sorted(f for f in os.listdir(d) if f.startswith("libmujoco.so") or f.startswith("libmujoco.")
                   and f.endswith(".dylib") or f == "mujoco.dll")
    if not names:
        raise OSError(f"no libmujoco in {d}")
    return os.path.join(d, max(names, key=len))


_PROBE = """<mujoco><option timestep="0.001"/><worldbody>
<body name="a" pos="0 0 1"><joint name="j1" type="hinge" axis="0 1 0" frictionloss="0.1"/>
<geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" contype="0" conaffinity="0"/>
<body name="b" pos="0.2 0 0"><joint name="j2" type="hinge" axis="0 1 0" frictionloss="0.1"/>
<geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" contype="0" conaffinity="0"/><site name="s" pos="0.2 0 0"/>
</body></body></worldbody><equality><connect body1="b" anchor="0.2 0 0" body2="world"/></equality></mujoco>"""


def _read(addr: int, ctype):
    return ctype.from_address(addr).value


@functools.cache
def layout() -> Layout:
    """Offsets of time, ne, nefc and the efc pointers in mjData, checked on a probe model.

    ``time`` sits just before ``energy[2]`` (a view the bindings give); ne and nefc are the 2nd and
    5th ints of the "variable sizes" block that follows ``timer[mjNTIMER]`` (mjdata.h since MuJoCo
    2.x); the efc pointers are found by their values. Raises ``RuntimeError`` when a check fails.
    """
    import mujoco

    m = mujoco.MjModel.from_xml_string(_PROBE)
    d = mujoco.MjData(m)
    base = d._address
    off_energy = d.energy.ctypes.data - base
    off_time = off_energy - 8
    d.time = 1234.5678125
    if _read(base + off_time, ctypes.c_double) != d.time:
        raise RuntimeError("mjData.time is not just before mjData.energy")
    d.time = 0.0
    n_timer = int(mujoco.mjtTimer.mjNTIMER)  # the enums end with their count
    off_warning = d.warning.number.ctypes.data - base - 4  # mjWarningStat = {int lastinfo; int number}
    n_warning = int(mujoco.mjtWarning.mjNWARNING)
    off_ncon = off_warning + 8 * n_warning + 16 * n_timer  # mjTimerStat = {double duration; int number} (16 B)
    off_ne, off_nefc = off_ncon + 4, off_ncon + 16
    checks = []
    for active in (1, 0):
        d.eq_active[0] = active
        mujoco.mj_forward(m, d)
        checks.append((_read(base + off_ne, ctypes.c_int), d.ne, _read(base + off_nefc, ctypes.c_int), d.nefc))
    if any(a != b or c != e for a, b, c, e in checks) or checks[0][1] == checks[1][1]:
        raise RuntimeError(f"mjData ne/nefc not at the expected offsets (read, bindings: {checks})")
    d.eq_active[0] = 1
    mujoco.mj_forward(m, d)
    want = {"efc_pos": d.efc_pos, "efc_force": d.efc_force, "efc_type": d.efc_type, "efc_id": d.efc_id}
    ptrs = {v.ctypes.data: k for k, v in want.items()}
    if len(ptrs) != 4 or 0 in ptrs:
        raise RuntimeError("probe model: efc arrays empty or aliased")
    found: dict[str, int] = {}
    off = off_energy + 16
    while len(found) < 4 and off < off_energy + 4096:  # pointer fields follow the info header
        v = _read(base + off, ctypes.c_void_p)
        if v in ptrs:
            found[ptrs[v]] = off
        off += 8
    if len(found) < 4:
        raise RuntimeError(f"mjData efc pointers not found (found {sorted(found)})")
    return Layout(time=off_time, ne=off_ne, nefc=off_nefc, **found)


@functools.cache
def _native() -> None:
    """Load ``libmujoco`` for the linker and check the mjData layout (once per process: facts of this machine)."""
    import llvmlite.binding as llvm

    llvm.load_library_permanently(_libmujoco_path())
    layout()


def _load() -> None:
    _native()
    from hapticopt.analysis.loop import _mujoco_kernels  # noqa: F401


def availability() -> str | None:
    """None when the compiled loops can run here, else why not (one line)."""
    return unavailable(_load, "the compiled MuJoCo loops")


def kernels():
    """The master's compiled kernels module (imported on first use: numba loads only when a plant runs); the
    3-PRRR's is :mod:`hapticopt.analysis.prrr.loop._mujoco_kernel` (load it after :func:`availability` says None)."""
    reason = availability()
    if reason is not None:
        raise RuntimeError(reason)
    from hapticopt.analysis.loop import _mujoco_kernels  # loaded by availability()

    return _mujoco_kernels


def warm_up() -> str | None:
    """Load (or compile) the master's kernels now by running them for zero ticks; returns why the compiled loops
    are unavailable (None: ready). For a worker to call at start (with the 3-PRRR's:
    :func:`hapticopt.analysis.prrr.loop.mujoco_plant.warm_up`)."""
    reason = availability()
    if reason is not None:
        return reason
    kernels().warm()
    return None


def needed_by(scene_names) -> bool:
    """Whether any of these bundled scenes runs on a MuJoCo plant (so a worker about to run them should
    :func:`warm_up` first). A name that does not load counts as not needing it (its run reports the error)."""
    for name in scene_names:
        try:
            if resolve(load_scene(name)).backend == Backend.MULTIBODY:
                return True
        except (InvalidInput, OSError, KeyError, ValueError):
            continue
    return False
