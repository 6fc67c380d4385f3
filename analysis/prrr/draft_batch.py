"""Batched draft evaluation of the 3-PRRR's registry evaluators.

Many designs at draft fidelity in one pass, with the same results and statuses as the
evaluators one by one (tested to 1e-9 relative, ``tests/analysis/prrr/test_draft_batch.py``, on
hand-picked hard cases and on a seeded sample within the bundled problem's bounds).
The verdicts are the evaluators' own rules (``statics.from_arrays``, ``structure.from_arrays``,
``workspace._result``, ``free_workspace.finish``, ``joint_limits.from_angles``,
``device_size.from_specs``, ``stability.evaluate``), several in the array forms each evaluator
provides for a whole chunk (``statics.from_arrays_many``, ``structure.ok_many``,
``workspace.result_rows``, ``joint_limits.from_ranges_many``, ``stability.evaluate_many``, each tested
equal to its per-design function); this module only computes the arrays they read, for a whole batch
at a time. A ``*_many`` pass that raises falls back to the per-design function for each design.

* **jax, one jitted vmap** (:func:`core_fn`) of the groups the wanted evaluators read
  (:func:`groups_for`): statics (``statics_arrays``), the reach-and-stroke workspace
  (``workspace_core`` at the draft sampling; its reach radius, emptiness and footprint also bound
  the collision-free cylinder: they do not depend on the radial sampling), the frame model's legs'
  stiffness terms (``frame_leg_terms``, default options, home pose: element parameters, springs and
  maps; the elements' stiffness, the assembly and the solves follow the jitted call over designs,
  ``frame_condense.condense_terms_many``, numpy or its numba kernel as the ``Compute`` says)
  and the joint ranges over the required cylinder
  (``joint_limits.cylinder_ranges_of``: the IK of the grid's in-plane points, the angles reduced to
  what the verdict reads inside the jitted call). Inputs are stacked with numpy (the frame's by
  ``frame_params.frame_params_many``, arrays over the batch); the batch is padded to
  the next power of two (at most :data:`MAX_CHUNK`; larger batches go in chunks), so a new batch
  size within a bucket costs no trace or compile (:data:`TRACES` counts traces); compiled code
  persists on disk (``hapticopt.design.jax_config``). The stability evaluator takes its stiffness
  limits from the statics row (where that row's verdict is ok).
* **numpy over all designs at once**: the interference poses (``workspace_sample_weights_many``:
  every design's sample points and weights in one pass, bit for bit the per-design function's; then
  one separating-axis pass over every pose of every design, ``interference_fast.deepest_joints``
  (compiled: the kernel builds the part frames from the pose IK's joint values, the cos / sin of the
  joint angles compiled too, and keeps each pose's deepest overlap) or ``interference_fast.check_joints``) and the collision-free radius (``free_workspace.free_radius_many``: the coarse
  column grid of every design in one pass, then each bisection in one pass). The column structure
  (moving parts translate together in z, fixed parts are prisms) is what makes one pose per
  column enough there. Pose IK is the numpy IK's (the single path's) values bit for bit: a numba kernel
  over poses for the arithmetic (``_interference_kernels.pose_ik_planar``) and numpy's arccos /
  arctan2, or numpy over every pose at once for small batches or without numba. The check prunes primitive
  pairs per pose (part boxes, primitive boxes, separating axes one at a time), which a fixed-shape
  jax program cannot do; on a CPU the pruned numpy pass was already the faster of the two, and its
  compiled kernel is faster still (measured: docs/workspace_interference.md).
* **two things at once**: the jax core is dispatched (:func:`start_core`: jax's asynchronous dispatch, XLA's
  own thread) before the interference check and collected after it (:func:`finish_core`), so the collision
  kernel and the core run on two cores; the compiled check's calls are split into shares of whole designs
  (:func:`_shares`) on ``compiled.threads()`` threads (the kernels release the GIL; a run's pool workers
  use one). Results are the same bits on one thread or several (tested); measured in docs/performance.md
  ("The batched draft evaluator at 2,000 designs/s").
* **numpy, one table per part layout**: the CAD part tables (``cad_arrays.part_tables_many``: the
  layout and its buildability rules on (n,) columns, tested equal to ``cad.part_specs``), the
  interference model's primitive tables from them (``interference_fast.models_from_tables``), the
  envelope (:func:`envelopes`) and workspace parameters (``workspace.workspace_params_many``), the
  analytic mass model and height (``device_size.from_tables``). A design that fails a layout rule, or
  lies within ``cad_arrays.NEAR`` of a rule's threshold or branch point, takes the per-design
  functions (``assembly.parts``, ``cad.part_specs``, ``device_size.from_specs``): same exception,
  same message.
* **per design (Python)**: the result records of the verdicts (the numbers they read come from the
  array passes above; the force-loop bandwidth of ``stability`` is a closed form over every design at once).

A design whose chain does not close takes the single path (``registry.evaluate_batch``); one whose
parts the CAD cannot lay out is batched for the kinematic evaluators, and the part evaluators
give their own early ``not-assemblable``. A step that raises for one design is returned as that
exception (the registry turns it into ``failed`` with its one failure policy); the other designs
and steps still run.
"""

from __future__ import annotations

import collections
import functools
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.analysis import compiled
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.analysis.prrr import assembly
from hapticopt.analysis.prrr import device_size as DS
from hapticopt.analysis.prrr import frame_condense
from hapticopt.analysis.prrr import frame_model as fm
from hapticopt.analysis.prrr import frame_params
from hapticopt.analysis.prrr import free_workspace as FW
from hapticopt.analysis.prrr import interference as IF
from hapticopt.analysis.prrr import interference_fast as FAST
from hapticopt.analysis.prrr import joint_limits as JL
from hapticopt.analysis.prrr import stability, statics, structure
from hapticopt.analysis.prrr import workspace as WS
from hapticopt.design.errors import HapticoptError, InvalidInput
from hapticopt.design.prrr import cad, cad_arrays
from hapticopt.design.prrr.kinematics import PrrrParams, leg_frames
from hapticopt.design.prrr.params import PrrrDesign

#: registry evaluators computed by the batch (``stability`` from the statics rows: see the docstring)
BATCHED = ("statics", "structural_stiffness", "workspace", "interference", "free_workspace", "device_size",
           "joint_limits")
#: largest padded batch of one jitted call (larger batches run in chunks of this size)
MAX_CHUNK = 1024
#: traces of the jitted functions by name (a trace precedes every compile; tests count them)
TRACES: collections.Counter = collections.Counter()

_REQUIRED_RADIUS = FW.DEFAULT_REQUIRED_DIAMETER / 2.0
_SMP = WS.SAMPLING[Fidelity.DRAFT]
_FREE = FW.SAMPLING[Fidelity.DRAFT]


def bucket(n: int, *, least: int = 1) -> int:
    """The padded size of a batch of ``n``: the next power of two ≥ max(n, least)."""
    return 1 << max(0, (max(n, least) - 1).bit_length())


class CoreInputs(NamedTuple):
    """Stacked inputs of :func:`core_fn` (numpy, leading batch axis) [SI]."""

    kin: PrrrParams
    spring: np.ndarray  # SEA spring k [N/m]
    force_limit: np.ndarray  # F_max per actuator [N]
    mass: np.ndarray  # end-effector mass M [kg]
    wp: WS.WorkspaceParams
    fp: fm.FrameParams


#: the core's groups of arrays and the evaluators that read them (the core computes only the groups
#: the batch's evaluators need: a sweep ``--only free_workspace`` does not pay for the frame model)
CORE_GROUPS = {"statics": ("statics", "stability"), "workspace": ("workspace", "free_workspace"),
               "frame": ("structural_stiffness",), "joint": ("joint_limits",)}


def groups_for(want: list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """The core groups the evaluators ``want`` read (in :data:`CORE_GROUPS` order)."""
    return tuple(g for g, names in CORE_GROUPS.items() if any(name in want for name in names))


def _core(inp: CoreInputs, groups: tuple[str, ...]) -> dict:
    TRACES["core"] += 1  # runs once per trace, not per call
    out = {}
    if "statics" in groups:
        out["statics"] = statics.statics_arrays(inp.kin, inp.spring, inp.force_limit, inp.mass, xp=jnp)
    if "workspace" in groups:
        out["workspace"] = WS.workspace_core(inp.wp, n_phi=_SMP.n_phi, n_r=_SMP.n_r, xp=jnp)
    if "frame" in groups:
        G, Ks, P, ik = fm.frame_leg_terms(inp.fp, jnp.zeros(3), fm.FrameOptions())  # assembled, solved in finish_core
        out["frame"] = {"G": G, "Ks": Ks, "P": P, "reachable": ik.reachable, "reach_margin": ik.reach_margin}
    if "joint" in groups:  # only the reductions the verdict reads leave XLA
        out["joint"] = JL.cylinder_ranges_of(inp.kin, _REQUIRED_RADIUS, xp=jnp)
    return out


@functools.cache
def core_fn(groups: tuple[str, ...] = tuple(CORE_GROUPS)):
    """The jitted, vmapped draft core of ``groups`` (one compile per padded batch size and groups)."""
    return jax.jit(jax.vmap(functools.partial(_core, groups=groups)))


_KIN_FIELDS = ("beta", "d1", "d2", "d3", "d4", "r4", "b5", "stroke")
#: the legs' u and t (3 legs, 3) of the numpy IK (``leg_frames``; they do not depend on β)
_LEGS = leg_frames(0.0, xp=np)
_EZ = np.array([0.0, 0.0, 1.0])


def stack_inputs(designs: list[PrrrDesign], wps: list[WS.WorkspaceParams] | None,
                 groups: tuple[str, ...] = tuple(CORE_GROUPS)) -> CoreInputs:
    """Numpy stacking of the core's inputs (no jax operation per design); the workspace and frame
    inputs only where ``groups`` read them (None otherwise: an empty pytree node)."""
    geo = [d.geometry for d in designs]
    kin = PrrrParams(*(np.array([float(getattr(g, f)) for g in geo]) for f in _KIN_FIELDS))
    fp = frame_params.frame_params_many(designs) if "frame" in groups else None
    wp = None
    if "workspace" in groups:
        wp = WS.WorkspaceParams(*(np.array([float(w[k]) for w in wps]) for k in range(len(wps[0]))))
    return CoreInputs(kin=kin, spring=np.array([d.actuator.spring for d in designs]),
                      force_limit=np.array([d.actuator.force_limit for d in designs]),
                      mass=np.array([d.end_effector.mass for d in designs]), wp=wp, fp=fp)


class PendingCore(NamedTuple):
    """A dispatched core call (:func:`start_core`): jax runs it asynchronously on its own threads while
    the caller does other work; :func:`finish_core` waits for it."""

    out: dict  # jax arrays (padded batch)
    n: int


def start_core(inp: CoreInputs, n: int, groups: tuple[str, ...] = tuple(CORE_GROUPS)) -> PendingCore:
    """Dispatch the core of ``groups`` on ``n`` stacked designs, padded to :func:`bucket` (n ≤ MAX_CHUNK),
    without waiting for it (jax's asynchronous dispatch: the compiled program runs on XLA's threads, which
    do not hold the GIL, so the numba collision kernels run meanwhile)."""
    if not groups:
        return PendingCore({}, n)
    size = bucket(n)
    pad = jax.tree.map(lambda x: np.concatenate([x, np.repeat(x[-1:], size - n, axis=0)]) if size > n else x, inp)
    return PendingCore(core_fn(groups)(pad), n)


def finish_core(pending: PendingCore, *, compute: Compute = DEFAULT) -> dict:
    """The numpy rows [:n] of a dispatched core (waits for it), the frame group assembled and solved
    (``frame_condense.condense_terms_many`` with ``compute``)."""
    n = pending.n
    out = jax.tree.map(lambda x: np.asarray(x)[:n], pending.out)
    if "frame" in out:  # the legs' assembly and solves outside XLA
        fr = out["frame"]
        terms = fr.pop("G"), fr.pop("Ks"), fr.pop("P")
        out["frame"] = {**frame_condense.condense_terms_many(*terms, fm.FrameOptions(), fm.LOAD_HEIGHT, compute=compute), **fr}
    return out


def run_core(inp: CoreInputs, n: int, groups: tuple[str, ...] = tuple(CORE_GROUPS), *,
             compute: Compute = DEFAULT) -> dict:
    """The core of ``groups`` on ``n`` stacked designs, padded to :func:`bucket` (n ≤ MAX_CHUNK);
    numpy rows [:n] (:func:`start_core` then :func:`finish_core`)."""
    return finish_core(start_core(inp, n, groups), compute=compute)


def _elbow_branch(elbow: np.ndarray, phi: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Joint angles (n, 3 legs, 3) [rad] of the elbow branch ``WS.ELBOW_BRANCH`` from the elbow angle and
    the in-plane angles φ, ψ (n, 3) (``kinematics.inverse_kinematics``' ``branch``)."""
    th1, th2 = (phi - psi, elbow) if WS.ELBOW_BRANCH == 0 else (phi + psi, -elbow)
    th1 = np.mod(th1 + np.pi, 2.0 * np.pi) - np.pi  # wrap to [−π, π)
    return np.stack([th1, th2, -(th1 + th2)], axis=-1)


class _Checker:
    """Collision checks of poses of many designs (owner index per pose), grouped by part layout."""

    def __init__(self, designs: list[PrrrDesign], models: dict[int, FAST.FastModel]) -> None:
        self.idx = np.array(sorted(models), dtype=int)
        geo = [d.geometry for d in designs]
        self.geo = {f: np.array([float(getattr(g, f)) for g in geo]) for f in _KIN_FIELDS + ("theta_1p",)}
        groups: dict[tuple, list[int]] = {}
        for i in self.idx:
            groups.setdefault(FAST.layout_key(models[i]), []).append(int(i))
        self.groups = []
        for members in groups.values():
            local = np.full(len(designs), -1)
            local[members] = np.arange(len(members))
            geometry = FAST.LegGeometry(*(self.geo[f][members] for f in FAST.LegGeometry._fields))
            batch = FAST.stack_models([models[i] for i in members])
            self.groups.append((local, batch, geometry, FAST.joint_tables(batch, geometry)))

    def pose_ik(self, owner: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sliders (n, 3) [m], elbow-branch joint angles (n, 3, 3) [rad] and reachability (n,) of poses
        ``pts`` (n, 3) [m] of designs ``owner``: the numpy IK's values bit for bit
        (``kinematics.inverse_kinematics``, the single path's), from the numba kernel
        ``_interference_kernels.pose_ik_planar`` (the arithmetic) and numpy's arccos / arctan2 on its
        outputs, or from :meth:`pose_ik_numpy` where the kernel is not loaded and the poses are fewer
        than ``interference_fast.KERNEL_AFTER_POSES`` (a small batch does not load numba for this) or
        where numba cannot load."""
        n = len(pts)
        kernels = "hapticopt.analysis.prrr._interference_kernels"
        if (n < FAST.KERNEL_AFTER_POSES and kernels not in sys.modules) or FAST.availability() is not None:
            return self.pose_ik_numpy(owner, pts)
        sliders, elbow, phi, psi, ok = self._planar_ik(owner, pts)
        return sliders, _elbow_branch(elbow, phi, psi), ok

    def _planar_ik(self, owner: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, ...]:
        """Sliders (n, 3) [m], the elbow angle and in-plane angles φ, ψ (n, 3) [rad] and reachability (n,):
        ``pose_ik_planar``'s arithmetic and numpy's arccos / arctan2 (needs the kernels loaded)."""
        from hapticopt.analysis.prrr import _interference_kernels as K  # loaded by availability()

        n = len(pts)
        g = self.geo
        beta = g["beta"]
        sliders, rho_v, rho_t, c2, y, x = (np.empty((n, 3)) for _ in range(6))
        ok = np.empty(n, dtype=np.bool_)
        K.pose_ik_planar(np.ascontiguousarray(owner, dtype=np.int64), np.ascontiguousarray(pts, dtype=np.float64),
                         np.cos(beta), np.sin(beta), np.tan(beta), *(g[f] for f in _KIN_FIELDS[1:]), _LEGS.u,
                         _LEGS.t, sliders, rho_v, rho_t, c2, y, x, ok)
        return sliders, np.arccos(c2), np.arctan2(rho_t, rho_v), np.arctan2(y, x), ok

    def pose_ik_numpy(self, owner: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`pose_ik` in numpy over every pose at once: ``inverse_kinematics``' operations
        element by element, each design's parameters gathered per pose (bit for bit the same values)."""
        g, o = self.geo, np.asarray(owner, dtype=int)
        beta = g["beta"]
        cb, sb = np.cos(beta), np.sin(beta)
        u, t = _LEGS.u, _LEGS.t
        d1, d2, d3, d4, r4, b5 = (g[f] for f in ("d1", "d2", "d3", "d4", "r4", "b5"))
        w = (-cb[:, None, None] * u + sb[:, None, None] * _EZ)[o]  # leg_frames' w, v per pose (n, 3, 3)
        v = (sb[:, None, None] * u + cb[:, None, None] * _EZ)[o]
        a0 = (d1[:, None, None] * u + d2[:, None, None] * t)[o]
        r5 = b5 * sb
        c_e = -(b5 + r4) / sb + r5 + d1 / np.tan(beta)
        half = g["stroke"] / 2.0
        rel = np.asarray(pts, dtype=float)[:, None, :] - b5[o, None, None] * w + r5[o, None, None] * _EZ - a0
        sliders = (np.sum(rel * w, axis=-1) - r4[o, None]) / sb[o, None]
        rel = rel - sliders[..., None] * _EZ
        rho_v = np.sum(rel * v, axis=-1)
        rho_t = np.sum(rel * t, axis=-1)
        D3, D4 = d3[o, None], d4[o, None]
        c2 = (rho_v**2 + rho_t**2 - D3**2 - D4**2) / (2.0 * D3 * D4)
        reach_ok = np.abs(c2) <= 1.0 + 1e-12
        c2 = np.clip(c2, -1.0, 1.0)
        psi = np.arctan2(D4 * np.sqrt(1.0 - c2**2), D3 + D4 * c2)
        stroke_ok = np.abs(sliders - c_e[o, None]) <= half[o, None] * (1.0 + 1e-12)
        return (sliders, _elbow_branch(np.arccos(c2), np.arctan2(rho_t, rho_v), psi),
                np.all(reach_ok & stroke_ok, axis=-1))

    def __call__(self, owner: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(collides, reachable, deepest overlap [m]) at poses ``pts`` (n, 3) of designs ``owner``.

        Where the compiled check runs (``interference_fast``'s rule: from ``KERNEL_AFTER_POSES`` checked
        poses on, numba loadable) and every layout group has joint tables: the pose IK's arithmetic and
        the joint angles' cos / sin compiled (``interference_fast.joint_cos_sin``), numpy's arccos /
        arctan2, and ``interference_fast.deepest_joints`` per group (no joint-angle or per-pair depth
        arrays; a group holding every pose is passed without copies). Otherwise :meth:`pose_ik` and
        ``interference_fast.check_joints``. The same values bit for bit either way (tested)."""
        n = len(pts)
        collides, reachable, depth = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n)
        if n == 0:
            return collides, reachable, depth
        if (FAST._POSES_CHECKED[0] + n < FAST.KERNEL_AFTER_POSES or FAST.availability() is not None
                or any(tables is None for *_, tables in self.groups)):
            return self._call_arrays(owner, pts, collides, reachable, depth)
        FAST._POSES_CHECKED[0] += n
        sliders, elbow, phi, psi, ok = self._planar_ik(owner, pts)
        trig = FAST.joint_cos_sin(elbow, phi, psi, WS.ELBOW_BRANCH)
        jobs = []
        for local, batch, geometry, tables in self.groups:
            lo = local[owner]
            sel = np.flatnonzero(lo >= 0)
            k = _kernel_threads(len(sel))
            if len(sel) == n and k == 1:  # one group holds every pose, one thread
                hit, deepest = FAST.deepest_joints(lo, pts, sliders, trig, ok, tables)
                return hit, ok, deepest
            jobs += [(part, lo, tables) for part in _shares(sel, owner, k)]

        def run(job) -> None:
            part, lo, tables = job
            if part[-1] - part[0] + 1 == len(part):  # a contiguous share: views, no copies
                part = slice(int(part[0]), int(part[-1]) + 1)
            hit, deepest = FAST.deepest_joints(lo[part], pts[part], sliders[part], tuple(x[part] for x in trig),
                                               ok[part], tables)
            collides[part], reachable[part], depth[part] = hit, ok[part], deepest

        _run_threaded(run, jobs)
        return collides, reachable, depth

    def _call_arrays(self, owner, pts, collides, reachable, depth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`__call__` through :meth:`pose_ik`'s joint angles and ``interference_fast.check_joints``
        (its rule: numpy, or the kernel where it runs)."""
        sliders, theta, ok = self.pose_ik(owner, pts)
        jobs = []
        for local, batch, geometry, tables in self.groups:
            sel = np.flatnonzero(local[owner] >= 0)
            jobs += [(part, local, batch, geometry, tables) for part in _shares(sel, owner, _kernel_threads(len(sel)))]

        def run(job) -> None:
            part, local, batch, geometry, tables = job
            res = FAST.check_joints(batch, local[owner[part]], pts[part], sliders[part], theta[part], ok[part],
                                    geometry, tables=tables)
            collides[part] = res.collides
            reachable[part] = res.reachable
            depth[part] = res.depth.max(axis=1) if res.depth.shape[1] else 0.0

        _run_threaded(run, jobs)
        return collides, reachable, depth


#: fewest poses per thread of a check (below, one thread: the hand-off costs more than it saves)
POSES_PER_THREAD = 2048


def _kernel_threads(n: int) -> int:
    """Threads for a check of ``n`` poses: ``compiled.threads()``, fewer for a small check, one where the
    collision kernel does not run (numpy path)."""
    if n < 2 * POSES_PER_THREAD or compiled.threads() == 1 or FAST.availability() is not None:
        return 1
    return max(1, min(compiled.threads(), n // POSES_PER_THREAD))


def _shares(sel: np.ndarray, owner: np.ndarray, k: int) -> list[np.ndarray]:
    """``sel`` (pose indices) in ``k`` contiguous shares of about equal size, each cut where the owner
    changes (a design's run of poses stays in one share: the kernel sets up each design once per run)."""
    if len(sel) == 0:
        return []
    cuts = [0]
    for j in range(1, k):
        c = max(cuts[-1], j * len(sel) // k)
        while 0 < c < len(sel) and owner[sel[c]] == owner[sel[c - 1]]:
            c += 1
        cuts.append(c)
    cuts.append(len(sel))
    return [sel[a:b] for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


@functools.cache
def _pool() -> ThreadPoolExecutor:
    """The kernel threads beside the calling one (made at first use, sized by ``compiled.threads()``)."""
    return ThreadPoolExecutor(max_workers=max(1, compiled.threads() - 1), thread_name_prefix="hapticopt-kernel")


def _run_threaded(fn, jobs: list) -> None:
    """``fn(job)`` for every job: on the calling thread and the pool's threads at once where there are
    several jobs (the collision kernel releases the GIL), the first error raised again here."""
    if len(jobs) <= 1:
        for job in jobs:
            fn(job)
        return
    futures = [_pool().submit(fn, job) for job in jobs[1:]]
    fn(jobs[0])
    for f in futures:
        f.result()


_CORNERS = np.array([[i, j, k] for i in (-1.0, 1.0) for j in (-1.0, 1.0) for k in (-1.0, 1.0)])


def envelopes(designs: list[PrrrDesign], models: dict[int, FAST.FastModel], specs: list[Any]) -> dict[int, float]:
    """:func:`hapticopt.design.prrr.cad.envelope_radius` [m] of the designs with primitive tables
    (index → radius), from those tables for every design of one part layout at once: the SOLID
    primitives of the base's and the carriages' parts at the home pose (``cad.part_frames_arrays``),
    box corners, cylinder end centres + radius, sphere centre + radius, largest distance from z
    (tested equal to the per-design function)."""
    out: dict[int, float] = {}
    layouts: dict[tuple, list[int]] = {}
    for i, m in models.items():
        layouts.setdefault(FAST.layout_key(m), []).append(i)
    for members in layouts.values():
        m0 = models[members[0]]
        body = _bodies(specs[members[0]], m0.part_names)
        fixed_part = np.array([b == "base" or b.startswith("carriage_") for b in body])
        sel = np.flatnonzero(fixed_part[m0.prim_part])
        if len(sel) == 0:
            out.update({i: 0.0 for i in members})
            continue
        k = len(members)
        g = {f: np.array([float(getattr(designs[i].geometry, f)) for i in members])
             for f in ("beta", "d1", "d2", "d3", "theta_1p")}
        frames = cad.part_frames_arrays(g["beta"], g["d1"], g["d2"], g["d3"], g["theta_1p"], np.zeros((k, 3)),
                                        np.zeros((k, 3, 2)), np.zeros((k, 3)))
        part = m0.prim_part[sel]
        Rf = np.stack([np.asarray(frames[m0.part_names[j]][0], dtype=float) for j in part], axis=1)  # (k, S, 3, 3)
        of = np.stack([np.asarray(frames[m0.part_names[j]][1], dtype=float) for j in part], axis=1)  # (k, S, 3)
        R = Rf @ np.stack([models[i].R[sel] for i in members])
        o = (Rf @ np.stack([models[i].o[sel] for i in members])[..., None])[..., 0] + of
        half = np.stack([models[i].half[sel] for i in members])  # box: a/2, b/2, c/2; cylinder: a, a, b/2
        kind = m0.kind[sel]
        corners = o[:, :, None] + (_CORNERS[None, None] * half[:, :, None]) @ np.swapaxes(R, -1, -2)
        box = np.max(np.hypot(corners[..., 0], corners[..., 1]), axis=-1)
        ends = o[:, :, None] + np.array([-1.0, 1.0])[None, None, :, None] * half[:, :, None, 2:] * R[:, :, None, :, 2]
        cyl = np.max(np.hypot(ends[..., 0], ends[..., 1]), axis=-1) + half[..., 0]
        sph = np.hypot(o[..., 0], o[..., 1]) + half[..., 0]
        r = np.where(kind == FAST._BOX, box, np.where(kind == FAST._CYL, cyl, sph))
        out.update({i: max(0.0, float(x)) for i, x in zip(members, r.max(axis=1))})
    return out


class _Blocked(Exception):
    """Stands for the part tables of a design whose parts cannot be laid out (``assembly.parts``)."""


class _Rows(NamedTuple):
    """Stands for the part tables of a design tabled by ``cad_arrays.part_tables_many``: row ``row``
    of ``tables``."""

    tables: Any
    row: int


def _part_tables(designs: list[PrrrDesign]) -> tuple[list[Any], list[Any], set[int]]:
    """(per design: its part tables — :class:`_Rows` of the array tables, or the per-design
    ``cad.part_specs`` dict, or the exception it raised, or :class:`_Blocked` —, the array tables by
    part layout with rows re-indexed to ``designs``, the designs whose parts cannot be laid out).

    ``cad_arrays.part_tables_many`` tables every design that passes the layout's rules clearly; the
    others (a rule fails, or a threshold within ``cad_arrays.NEAR``) take the per-design functions:
    ``assembly.parts`` (not-assemblable, with its message) and ``cad.part_specs``."""
    groups, rest = cad_arrays.part_tables_many(designs)
    specs: list[Any] = [None] * len(designs)
    for t in groups:
        for k, i in enumerate(t.index.tolist()):
            specs[i] = _Rows(t, k)
    no_parts = set()
    for i in rest.tolist():
        if assembly.parts(designs[i]):
            no_parts.add(i)
            specs[i] = _Blocked()
        else:
            specs[i] = _guard(cad.part_specs, designs[i])
    return specs, groups, no_parts


def _bodies(spec: Any, names: tuple[str, ...]) -> tuple[str, ...]:
    """The rigid body of each part ``names`` of a design's part tables (:func:`_part_tables`)."""
    if isinstance(spec, _Rows):
        return spec.tables.bodies
    return tuple(spec[name].body for name in names)


def _workspace_params(designs: list[PrrrDesign], specs: list[Any], env: dict[int, float]) -> list[WS.WorkspaceParams]:
    """``WS.workspace_params`` of every design: one table for those whose envelope is known (from their
    primitive tables, or the rail-circle bound of ``WS.base_envelope`` where the CAD raised), the
    per-design function for the rest."""
    known = dict(env)
    for i, (d, s) in enumerate(zip(designs, specs)):
        if i not in known and isinstance(s, (HapticoptError, _Blocked)):  # WS.base_envelope's bound where the CAD raises
            known[i] = max(d.structure.base_radius, d.geometry.r_p + d.structure.rail_width / 2.0)
    idx = sorted(known)
    rows = dict(zip(idx, WS.workspace_params_many([designs[i] for i in idx], np.array([known[i] for i in idx]))))
    return [rows[i] if i in rows else WS.workspace_params(d, specs=s if isinstance(s, dict) else None)
            for i, (d, s) in enumerate(zip(designs, specs))]


def _guard(fn, *args, **kw) -> Any:
    """``fn(*args, **kw)``, or the exception it raised (the registry's failure policy applies)."""
    try:
        return fn(*args, **kw)
    except Exception as exc:  # noqa: BLE001 - a failure is a value for the registry
        return exc


def evaluate_many(designs: list[PrrrDesign], *, only: tuple[str, ...] | None = None
                  ) -> list[tuple[dict[str, Any], dict[str, float]]]:
    """Draft results of ``designs``: per design (evaluator name → result or the exception raised,
    evaluator name → seconds, the batch's wall time of that step divided by the batch size)."""
    out: list[tuple[dict[str, Any], dict[str, float]]] = []
    for c in range(0, len(designs), MAX_CHUNK):
        out.extend(_chunk(list(designs[c:c + MAX_CHUNK]), only))
    return out


def _chunk(designs: list[PrrrDesign], only: tuple[str, ...] | None) -> list[tuple[dict[str, Any], dict[str, float]]]:
    n = len(designs)
    want = [name for name in BATCHED + ("stability",) if only is None or name in only]
    res: list[dict[str, Any]] = [{} for _ in designs]
    tim: dict[str, float] = {}
    draft = Fidelity.DRAFT

    t0 = time.perf_counter()
    # a design whose parts cannot be laid out (its chain closes: the registry sends the others to the
    # single path) is batched for the kinematic evaluators; the evaluators of its parts return their
    # own early ``not-assemblable`` (their single path, no part tables built)
    groups = groups_for(want)
    with_parts = any(name in want for name in ("workspace", "free_workspace", "interference", "device_size"))
    specs, tables, no_parts = _part_tables(designs) if with_parts else ([None] * n, [], set())
    # primitive tables (interference, free workspace) and the envelope of every design at once from them
    models: dict[int, FAST.FastModel] = {}
    model_errors: dict[int, Exception] = {}
    wps = None
    if "workspace" in groups or "interference" in want:
        for t in tables:
            models.update(zip(t.index.tolist(), FAST.models_from_tables([designs[i] for i in t.index], t)))
        for i, d in enumerate(designs):
            if isinstance(specs[i], dict):
                m = _guard(FAST.prepare, d, specs=specs[i])
                if isinstance(m, Exception):
                    model_errors[i] = m
                else:
                    models[i] = m
        wps = _workspace_params(designs, specs, envelopes(designs, models, specs))
    pending = start_core(stack_inputs(designs, wps, groups), n, groups)
    t_core = time.perf_counter() - t0

    # while XLA computes the core on its own threads: the collision check of the interference poses
    # (it reads the part tables and workspace parameters, not the core)
    check_specs = list(specs)  # a design whose primitive tables failed: that exception for the checks
    for i, err in model_errors.items():
        check_specs[i] = err
    if "interference" in want or "free_workspace" in want:
        check = _Checker(designs, models)
    if "interference" in want:
        for i in no_parts:
            res[i]["interference"] = _guard(IF.evaluate, designs[i], fidelity=draft)
        t2 = time.perf_counter()
        _interference(designs, check_specs, wps, check, res, t2)
        tim["interference"] = (time.perf_counter() - t2) / n
    t_wait = time.perf_counter()
    arrays = finish_core(pending)
    t_core += time.perf_counter() - t_wait

    def row(group: str, i: int) -> dict:
        return {k: v[i] for k, v in arrays[group].items()}

    t1 = time.perf_counter()
    if "statics" in want:
        _many(res, "statics", designs, statics.from_arrays_many, arrays["statics"],
              one=lambda i: _guard(statics.from_arrays, designs[i], row("statics", i)))
    if "joint_limits" in want:
        by_ranges = functools.partial(JL.from_ranges_many, n_points=JL.grid_size(), fidelity=draft, t0=t1)
        _many(res, "joint_limits", designs, by_ranges, arrays["joint"],
              one=lambda i: _guard(lambda: by_ranges([designs[i]], jax.tree.map(lambda v: v[i:i + 1], arrays["joint"]))[0]))
    if "structural_stiffness" in want:
        ok = _guard(structure.ok_many, arrays["frame"])
        ok = [False] * n if isinstance(ok, Exception) else ok.tolist()
        options = fm.FrameOptions()
        for i, (d, frame_row) in enumerate(zip(designs, _rows(arrays["frame"]))):
            res[i]["structural_stiffness"] = (  # a row not ok (or a failed pass): the per-design step
                structure.from_ok_arrays(frame_row, p=np.zeros(3), load_height=fm.LOAD_HEIGHT, options=options)
                if ok[i] else _guard(_structure, d, frame_row))
    if "workspace" in want or "free_workspace" in want:
        ws_rows = WS.result_rows(arrays["workspace"])
        for i, vals in enumerate(ws_rows):
            res[i]["workspace"] = _guard(WS._result_of, vals, _REQUIRED_RADIUS, draft)
    for i, d in enumerate(designs):
        if "device_size" in want and not isinstance(specs[i], _Rows):
            res[i]["device_size"] = (_guard(DS.evaluate, d, fidelity=draft) if i in no_parts
                                     else DS.failed(specs[i], t1) if isinstance(specs[i], HapticoptError)
                                     else _guard(DS.from_specs, d, specs[i], t1))
    if "device_size" in want:
        for t in tables:
            sizes = _guard(DS.from_tables, t, t1)
            for k, i in enumerate(t.index.tolist()):
                res[i]["device_size"] = sizes if isinstance(sizes, Exception) else sizes[k]
    t_rows = time.perf_counter() - t1
    for name in ("statics", "structural_stiffness", "workspace", "joint_limits", "device_size"):
        tim[name] = (t_core + t_rows) / (5 * n)

    for i in no_parts:
        if "free_workspace" in want:  # its verdict reads the batch's core: not-assemblable before the check
            res[i]["free_workspace"] = _guard(FW.finish, designs[i], ws_rows[i], None, fidelity=draft, t0=t1)
    if "free_workspace" in want:
        t3 = time.perf_counter()
        _free_workspace(designs, check_specs, ws_rows, check, res, t3)
        tim["free_workspace"] = (time.perf_counter() - t3) / n
    if "workspace" not in want:
        for r in res:
            r.pop("workspace", None)
    if "stability" in want:
        t4 = time.perf_counter()
        _stability(designs, arrays, res)
        tim["stability"] = (time.perf_counter() - t4) / n
    return [(r, {k: tim[k] for k in r}) for r in res]


def _rows(group: dict) -> list[dict]:
    """Per-design rows of a group of the core's stacked arrays (leading axis: the designs): the values
    ``v[i]`` of each array (row views, numpy scalars), split by one ``list`` per array."""
    return [dict(zip(group, vals)) for vals in zip(*(list(v) for v in group.values()))]


def _many(res: list[dict], name: str, designs: list[PrrrDesign], fn, *arrays, one) -> None:
    """``res[i][name]`` of every design from ``fn(designs, *arrays)`` (a ``*_many`` result step over the
    whole chunk); where that pass raises, ``one(i)`` gives each design's own result or exception."""
    found = _guard(fn, designs, *arrays)
    for i in range(len(designs)):
        res[i][name] = one(i) if isinstance(found, Exception) else found[i]


def _stability(designs: list[PrrrDesign], arrays: dict, res: list[dict]) -> None:
    """``stability`` of every design: the designs whose statics row gives their stiffness limits
    (:func:`_limits`) in one :func:`stability.evaluate_many`, the others one by one."""
    rows, limits = [], []
    for i, d in enumerate(designs):
        lim = _limits(d, arrays, i, res[i])
        if lim is None:
            res[i]["stability"] = _guard(stability.evaluate, d, fidelity=Fidelity.DRAFT)
        else:
            rows.append(i)
            limits.append(lim)
    if rows:
        found = _guard(stability.evaluate_many, [designs[i] for i in rows], limits=np.array(limits))
        for k, i in enumerate(rows):  # where the pass raised, each design's own result or exception
            res[i]["stability"] = (_guard(stability.evaluate, designs[i], fidelity=Fidelity.DRAFT, limits=limits[k])
                                   if isinstance(found, Exception) else found[k])


def _limits(design: PrrrDesign, arrays: dict, i: int, found: dict) -> np.ndarray | None:
    """The stiffness limits of the batch's statics row for ``stability``, where the statics verdict
    on that row is ok; None (the single path's numpy statics) otherwise: near a singular J the
    numbers are rounding garbage that differs between numpy and XLA."""
    if "statics" not in arrays:
        return None
    st = found.get("statics")
    if st is None:
        st = _guard(statics.from_arrays, design, {k: v[i] for k, v in arrays["statics"].items()})
    if isinstance(st, Exception) or st.status is not Status.OK:
        return None
    return arrays["statics"]["stiffness_limit"][i]


def _structure(design: PrrrDesign, out: dict) -> Any:
    """The frame result from the batch's row; a design whose verdict is not ok is solved again by
    the single numpy path: near a singular stiffness matrix the numbers are rounding garbage that
    differs between LAPACK and XLA, and so could the verdict read from them (measured: β = 89.999999°
    gave ``singular`` in numpy and ``not-positive-definite`` in jax). Rare, and it keeps the statuses equal."""
    try:
        result = structure.from_arrays(design, out, p=np.zeros(3), load_height=fm.LOAD_HEIGHT,
                                       options=fm.FrameOptions())
        if result.status is not structure.Status.OK:
            result = structure.structural_stiffness(design)
        return result
    except InvalidInput as exc:
        return structure.failed(str(exc))


def _samples(designs, specs, wps) -> dict[int, Any]:
    """The interference sample (points, weights) of every design with part tables or an exception for
    them (not :class:`_Blocked`): ``WS.workspace_sample_weights_many`` in one pass (equal to the
    per-design function bit for bit), or, should that raise, the per-design function with its own
    exception per design."""
    idx = [i for i in range(len(designs)) if not isinstance(specs[i], _Blocked)]
    many = _guard(WS.workspace_sample_weights_many, [designs[i] for i in idx], [wps[i] for i in idx],
                  **WS.INTERFERENCE_SAMPLING)
    if not isinstance(many, Exception):
        return dict(zip(idx, many))
    return {i: _guard(WS.workspace_sample_weights, designs[i], **WS.INTERFERENCE_SAMPLING, wp=wps[i]) for i in idx}


def _interference(designs, specs, wps, check, res, t0) -> None:
    owners, pts_all, weights = [], [], {}
    samples = _samples(designs, specs, wps)
    for i, d in enumerate(designs):
        if isinstance(specs[i], _Blocked):
            continue
        # the order of interference_fast.interference_fractions: an empty sample is (0, 0) before
        # the part tables are needed
        sample = samples[i]
        if isinstance(sample, Exception):
            res[i]["interference"] = sample
            continue
        pts, w = sample
        if len(pts) and w.sum() > 0:
            if isinstance(specs[i], HapticoptError):
                res[i]["interference"] = IF.failed(specs[i], t0)
                continue
            if isinstance(specs[i], Exception):
                res[i]["interference"] = specs[i]
                continue
            owners.append(np.full(len(pts), i))
            pts_all.append(pts)
        weights[i] = w
    span: dict[int, slice] = {}  # each checked design's poses: one contiguous run, in design order
    if owners:
        owner = np.concatenate(owners)
        collides, _, depth = check(owner, np.concatenate(pts_all))
        share = np.clip(depth / FAST.OVERLAP_SCALE, 0.0, 1.0)
        start = 0
        for o in owners:
            span[int(o[0])] = slice(start, start + len(o))
            start += len(o)
    for i, w in weights.items():
        if i in span:
            removed, overlap = FAST.fractions_of(w, collides[span[i]], share[span[i]])
        else:
            removed, overlap = 0.0, 0.0
        res[i]["interference"] = IF.from_fractions(removed, overlap, t0)


def _blocked_tabled(design: PrrrDesign, spec: Any) -> str | None:
    """``assembly.check(design, with_parts=True)`` of a design with array part tables (:class:`_Rows`):
    its parts are laid out (``cad_arrays`` tables only designs that pass ``cad.layout``'s rules clearly),
    so its chain closure alone (cached), without the CAD layout (≈ 0.16 ms a design not seen before);
    None for the others (the evaluator asks ``assembly.check`` itself)."""
    return assembly.closure(design) if isinstance(spec, _Rows) else None


def _free_workspace(designs, specs, ws_rows, check, res, t0) -> None:
    """``free_workspace`` of every design that has part tables (or their exception); ``ws_rows``: the
    workspace core's rows as Python floats (``WS.result_rows``: what ``FW.finish`` reads of the core)."""
    todo, r_max = [], []
    for i, d in enumerate(designs):
        if isinstance(specs[i], _Blocked):
            continue
        core = ws_rows[i]
        rm = FW.reach_limit(d, core)
        if bool(core["empty"]) or rm <= 0.0:
            res[i]["free_workspace"] = _guard(FW.finish, d, core, None, fidelity=Fidelity.DRAFT, t0=t0,
                                              blocked=_blocked_tabled(d, specs[i]))
        elif isinstance(specs[i], HapticoptError):
            res[i]["free_workspace"] = _guard(FW.finish, d, core, specs[i], fidelity=Fidelity.DRAFT, t0=t0)
        elif isinstance(specs[i], Exception):
            res[i]["free_workspace"] = specs[i]
        else:
            todo.append(i)
            r_max.append(rm)
    if not todo:
        return
    idx = np.asarray(todo)
    stroke = np.array([designs[i].geometry.stroke for i in todo])
    beta = np.array([designs[i].geometry.beta for i in todo])

    def collides(owner, phi, r):
        pts = FW.column_poses_of(stroke[owner], beta[owner], phi, r)
        hit, reach, _ = check(idx[owner], pts)
        return hit | ~reach

    r_free, n_chk, n_hit = FW.free_radius_many(collides, np.asarray(r_max), n_phi=_FREE.n_phi, n_r=_FREE.n_r,
                                               n_bisect=_FREE.n_bisect)
    for k, i in enumerate(todo):
        res[i]["free_workspace"] = _guard(FW.finish, designs[i], ws_rows[i],
                                          (float(r_free[k]), int(n_chk[k]), int(n_hit[k])),
                                          fidelity=Fidelity.DRAFT, t0=t0, blocked=_blocked_tabled(designs[i], specs[i]))
