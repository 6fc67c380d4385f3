"""Batched draft evaluation of the 3-PRRR's registry evaluators: many designs at draft fidelity in one
pass, with the results and statuses of the evaluators one by one (tested to 1e-9 relative,
``tests/analysis/prrr/test_draft_batch.py``).

The verdicts are the evaluators' own rules, several in the array forms each evaluator provides for a
whole chunk (``statics.from_arrays_many``, ``structure.ok_many``, ``workspace.result_rows``,
``joint_limits.from_ranges_many``, ``stability.evaluate_many``, ``free_workspace.free_radius_many``,
``interference_fast.deepest_joints``); this module computes the arrays they read, for a whole batch at a
time. A ``*_many`` pass that raises falls back to the per-design function for each design.

* **jax, one jitted vmap** (:func:`core_fn`) of the groups the wanted evaluators read (:func:`groups_for`):
  statics, the reach-and-stroke workspace, the frame model's legs' stiffness terms (assembled and solved
  after the call by ``frame_condense.condense_terms_many``, numpy or its numba kernel as the ``Compute``
  says), the joint ranges over the required cylinder. The batch is padded to
  the next power of two (at most :data:`MAX_CHUNK`), so a new size within a bucket costs no trace
  (:data:`TRACES` counts traces).
* **numpy, one table per part layout**: the CAD part tables (``layout.part_tables_many``), the
  collision check's primitive tables, the envelope (:func:`envelopes`), the workspace parameters and the
  device size. A design that fails a layout rule gets that rule's exception and message (the layout's
  first failed rule, as for one design).
* **the collision check** of every interference and free-workspace pose of every design: the one IK
  (``kinematics.inverse_kinematics``, numpy, batch-first over all poses) and the numba kernel, on
  ``compute.thread_count()`` threads, each a share of whole designs (:func:`_shares`), while XLA computes
  the core (:func:`start_core` dispatches it, :func:`finish_core` collects it). Results are the same bits
  at any thread count (tested).

A design whose chain does not close takes the single path (``registry.evaluate_batch``); one whose
parts the CAD cannot lay out is batched for the kinematic evaluators, and the part evaluators give their
own early ``not-assemblable``. A step that raises for one design is returned as that exception (the
registry turns it into ``failed``); the other designs and steps still run.
"""

from __future__ import annotations

import collections
import functools
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.prrr.geometry import device_size as DS
from hapticopt.analysis.prrr.structure import frame_condense
from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.prrr.structure import frame_params
from hapticopt.analysis.prrr.collision import free_workspace as FW
from hapticopt.analysis.prrr.collision import interference as IF
from hapticopt.analysis.prrr.collision import interference_fast as FAST
from hapticopt.analysis.prrr.geometry import joint_limits as JL
from hapticopt.analysis.prrr.loop import stability
from hapticopt.analysis.prrr.structure import strength
from hapticopt.analysis.prrr.structure import statics, stiffness as structure
from hapticopt.analysis.prrr.geometry import workspace as WS
from hapticopt.design.errors import HapticoptError, InvalidInput
from hapticopt.design.prrr import cad, layout as prrr_layout
from hapticopt.design.prrr.kinematics import PrrrParams, inverse_kinematics
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


class _Checker:
    """Collision checks of poses of many designs (owner index per pose), grouped by part layout."""

    def __init__(self, designs: list[PrrrDesign], models: dict[int, FAST.FastModel], compute: Compute = DEFAULT
                 ) -> None:
        self.compute = compute
        geo = [d.geometry for d in designs]
        self.geo = {f: np.array([float(getattr(g, f)) for g in geo]) for f in _KIN_FIELDS + ("theta_1p",)}
        groups: dict[tuple, list[int]] = {}
        for i in sorted(models):
            groups.setdefault(FAST.layout_key(models[i]), []).append(int(i))
        self.groups = []
        for members in groups.values():
            local = np.full(len(designs), -1)
            local[members] = np.arange(len(members))
            geometry = FAST.LegGeometry(*(self.geo[f][members] for f in FAST.LegGeometry._fields))
            batch = FAST.stack_models([models[i] for i in members])
            self.groups.append((local, FAST.joint_tables(batch, geometry)))

    def __call__(self, owner: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(collides, reachable, deepest overlap [m]) at poses ``pts`` (n, 3) of designs ``owner``: the one
        IK (each pose with its design's parameters) and ``interference_fast.deepest_trig`` per layout group,
        in shares of whole designs on :func:`_kernel_threads` threads of the checker's ``compute``. The IK
        runs as the checker's ``compute`` says (:func:`_ik_compiled`): compiled per pose inside each thread's
        share (``interference_fast.pose_joints``: the same text and bits as the numpy IK), or
        ``kinematics.inverse_kinematics`` in numpy over every pose first."""
        n = len(pts)
        collides, depth = np.zeros(n, bool), np.zeros(n)
        if n == 0:
            return collides, np.zeros(n, bool), depth
        owner = np.ascontiguousarray(owner, dtype=np.int64)
        pts = np.ascontiguousarray(pts, dtype=np.float64)
        compiled = _ik_compiled(n, self.compute)
        if compiled:
            joints = (np.empty((n, 3)),) + tuple(np.empty((n, 3)) for _ in range(4)) + (np.zeros(n, bool),)
        else:
            ik = inverse_kinematics(PrrrParams(*(self.geo[f][owner] for f in _KIN_FIELDS)), pts, xp=np)
            joints = (ik.sliders,) + FAST.joint_trig(ik.theta[:, WS.ELBOW_BRANCH]) + (ik.reachable,)
        jobs, covered = [], np.zeros(n, bool)
        for local, tables in self.groups:
            lo = local[owner]
            sel = np.flatnonzero(lo >= 0)
            covered[sel] = True
            jobs += [(part, lo, tables) for part in _shares(sel, owner, _kernel_threads(len(sel), self.compute))]
        if compiled and not covered.all():  # poses of designs without part tables: reachability only
            FAST.pose_joints(np.flatnonzero(~covered), owner, pts, self.geo, WS.ELBOW_BRANCH, joints)

        def run(job) -> None:
            part, lo, tables = job
            if compiled:
                FAST.pose_joints(part, owner, pts, self.geo, WS.ELBOW_BRANCH, joints)
            if part[-1] - part[0] + 1 == len(part):  # a contiguous share: views, no copies
                part = slice(int(part[0]), int(part[-1]) + 1)
            sliders, *trig, ok = (x[part] for x in joints)
            collides[part], depth[part] = FAST.deepest_trig(lo[part], pts[part], sliders, tuple(trig), ok, tables)

        _run_threaded(run, jobs)
        return collides, joints[-1], depth


#: fewest poses of a check whose IK runs compiled with ``Compute(backend="auto")`` (below, numpy's array
#: IK costs less than the call's set-up; the collision kernel is loaded either way)
IK_COMPILED_FROM_POSES = 512


def _ik_compiled(n: int, compute: Compute) -> bool:
    """Whether a check of ``n`` poses runs the compiled IK (``interference_fast.pose_joints``):
    ``compute.use_numba(n, IK_COMPILED_FROM_POSES)``, where the collision kernel loads."""
    return compute.use_numba(n, IK_COMPILED_FROM_POSES) and FAST.availability() is None


#: fewest poses per thread of a check (below, one thread: the hand-off costs more than it saves)
POSES_PER_THREAD = 2048


def _kernel_threads(n: int, compute: Compute) -> int:
    """Threads for a check of ``n`` poses: ``compute.thread_count()``, fewer for a small check (at least
    :data:`POSES_PER_THREAD` poses each)."""
    return max(1, min(compute.thread_count(), n // POSES_PER_THREAD))


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


def _run_threaded(fn, jobs: list) -> None:
    """``fn(job)`` for every job: the first on the calling thread, the others on a pool made for this call
    (the kernel releases the GIL), the first error raised again here. Making, using and shutting down a pool
    costs little against the :data:`POSES_PER_THREAD` or more poses of kernel work of each share."""
    if len(jobs) <= 1:
        for job in jobs:
            fn(job)
        return
    with ThreadPoolExecutor(max_workers=len(jobs) - 1, thread_name_prefix="hapticopt-kernel") as pool:
        futures = [pool.submit(fn, job) for job in jobs[1:]]
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
    """Stands for the part tables of a design tabled by ``layout.part_tables_many``: row ``row``
    of ``tables``."""

    tables: Any
    row: int


def _part_tables(designs: list[PrrrDesign]) -> tuple[list[Any], list[Any], set[int]]:
    """(per design: its part tables — :class:`_Rows` of the array tables, or the per-design
    ``cad.part_specs`` dict, or the exception it raised, or :class:`_Blocked` —, the array tables by
    part layout with rows re-indexed to ``designs``, the designs whose parts cannot be laid out).

    ``layout.part_tables_many`` tables every design that passes the layout's rules; the others are
    refused by ``assembly.parts`` (not-assemblable, with its message)."""
    groups, rest = prrr_layout.part_tables_many(designs)
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


def evaluate_many(designs: list[PrrrDesign], *, only: tuple[str, ...] | None = None, compute: Compute = DEFAULT
                  ) -> list[tuple[dict[str, Any], dict[str, float]]]:
    """Draft results of ``designs``: per design (evaluator name → result or the exception raised,
    evaluator name → seconds, the batch's wall time of that step divided by the batch size). ``compute``:
    the collision check's threads (``compute.thread_count()``)."""
    out: list[tuple[dict[str, Any], dict[str, float]]] = []
    for c in range(0, len(designs), MAX_CHUNK):
        out.extend(_chunk(list(designs[c:c + MAX_CHUNK]), only, compute))
    return out


def _chunk(designs: list[PrrrDesign], only: tuple[str, ...] | None, compute: Compute
           ) -> list[tuple[dict[str, Any], dict[str, float]]]:
    n = len(designs)
    want = [name for name in BATCHED + ("stability", "strength") if only is None or name in only]
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
        check = _Checker(designs, models, compute)
    if "interference" in want:
        for i in no_parts:
            res[i]["interference"] = _guard(IF.evaluate, designs[i], fidelity=draft)
        t2 = time.perf_counter()
        _interference(designs, check_specs, wps, check, res, t2)
        tim["interference"] = (time.perf_counter() - t2) / n
    t_wait = time.perf_counter()
    arrays = finish_core(pending, compute=compute)
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
    if "strength" in want:  # the frame's member stresses: the per-design step (one frame solve at the home pose)
        t5 = time.perf_counter()
        for i, d in enumerate(designs):
            res[i]["strength"] = _guard(strength.evaluate, d, fidelity=draft)
        tim["strength"] = (time.perf_counter() - t5) / n
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
    differs between LAPACK and XLA, and so could the verdict read from them (at β = 89.999999° numpy says
    ``singular``, jax ``not-positive-definite``). Rare, and it keeps the statuses equal."""
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
    its parts are laid out (``layout`` tables only designs that pass its rules),
    so its chain closure alone (cached), without the CAD layout;
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
