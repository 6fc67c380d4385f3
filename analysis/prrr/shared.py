"""The steps several 3-PRRR evaluators take for one design, each taken once per registry call.

``registry.evaluate_all`` runs one design's evaluators one after another; the workspace, free
workspace and interference evaluators each need the CAD part tables (``cad.part_specs``) and the
envelope of the fixed parts and carriages (``workspace.base_envelope``), the interference and free
workspace evaluators the primitive tables of the collision check (``interference_fast.prepare``), and
the device size evaluator the part tables again and their layout (``cad.layout``, for the height); the statics and stability evaluators the statics; the free workspace's passes and the interference
samples are checked by one point checker (``interference_fast.point_checker``: the design's stacked
tables and joint tables once); the workspace and free workspace evaluators each
compute the reach core (``workspace.workspace_core``), the latter reading only its entries that do
not depend on the radial sampling. :class:`DesignSteps` holds one design and takes each
of these steps the first time an evaluator asks for it, then hands the same value (or re-raises the
same exception) to the next: the evaluators' results are those of taking each step themselves.

It is made by the registry for one ``evaluate_all`` call and passed explicitly (``shared=``, part of the
one evaluator convention: docs/architecture.md) to the evaluators whose registry entry says they take
it; nothing outlives the call. Every step is a pure
function of the frozen design, so the memo is keyed by the design itself: a step asked for another
design raises.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hapticopt.design.errors import HapticoptError, InvalidInput
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr.params import PrrrDesign


class DesignSteps:
    """The shared steps of one design (see the module docstring)."""

    def __init__(self, design: PrrrDesign) -> None:
        self.design = design
        self._done: dict[str, Any] = {}

    def _step(self, design: PrrrDesign, name: str, fn) -> Any:
        if design is not self.design:
            raise InvalidInput(f"shared steps of design {self.design.name!r} asked for design {design.name!r}: "
                               "allowed only the design they were made for")
        if name not in self._done:
            try:
                self._done[name] = (True, fn())
            except HapticoptError as exc:  # a value of the step (the CAD refuses the design): kept
                self._done[name] = (False, exc)
        ok, value = self._done[name]
        if not ok:
            raise value
        return value

    def statics(self, design: PrrrDesign) -> Any:
        """:func:`hapticopt.analysis.prrr.structure.statics.evaluate` of ``design`` (closed forms, the same at every
        fidelity): the statics evaluator's result and the stability evaluator's stiffness limits."""
        from hapticopt.analysis.prrr.structure import statics  # noqa: PLC0415

        return self._step(design, "statics", lambda: statics.evaluate(design))

    def layout(self, design: PrrrDesign) -> Any:
        """:func:`hapticopt.design.prrr.cad.layout` of ``design`` (raises as it does): the part tables'
        and the device height's."""
        return self._step(design, "layout", lambda: cad_prrr.layout(design))

    def part_specs(self, design: PrrrDesign) -> dict:
        """:func:`hapticopt.design.prrr.cad.part_specs` of ``design`` from the shared :meth:`layout`
        (raises as it does)."""
        return self._step(design, "part_specs", lambda: cad_prrr.part_specs(design, lay=self.layout(design)))

    def envelope(self, design: PrrrDesign) -> float:
        """:func:`hapticopt.analysis.prrr.geometry.workspace.base_envelope` of ``design`` [m], from the shared
        part tables where the CAD lays the parts out."""
        from hapticopt.analysis.prrr.geometry import workspace  # noqa: PLC0415  (workspace imports this module's users)

        def envelope() -> float:
            try:
                specs = self.part_specs(design)
            except HapticoptError:  # base_envelope's fallback (it would try the part tables again)
                return workspace.fallback_envelope(design)
            return workspace.base_envelope(design, specs=specs)

        return self._step(design, "envelope", envelope)

    def fast_model(self, design: PrrrDesign) -> Any:
        """:func:`hapticopt.analysis.prrr.collision.interference_fast.prepare` of ``design`` from the shared
        part tables (raises as it does)."""
        from hapticopt.analysis.prrr.collision import interference_fast  # noqa: PLC0415

        return self._step(design, "fast_model",
                          lambda: interference_fast.prepare(design, specs=self.part_specs(design)))

    def point_checker(self, design: PrrrDesign) -> Any:
        """:func:`hapticopt.analysis.prrr.collision.interference_fast.point_checker` of the shared primitive tables
        in the elbow branch (``workspace.ELBOW_BRANCH``, the branch the free workspace and interference
        evaluators check; raises as :meth:`fast_model` does): their per-design steps once for the call."""
        from hapticopt.analysis.prrr.collision import interference_fast  # noqa: PLC0415

        return self._step(design, "point_checker", lambda: interference_fast.point_checker(
            self.fast_model(design), branch=interference_fast.ELBOW_BRANCH))

    def workspace_core(self, design: PrrrDesign, wp: Any, *, n_phi: int, n_r: int) -> dict:
        """:func:`hapticopt.analysis.prrr.geometry.workspace.workspace_core` of ``wp`` (numpy) at ``n_phi``, ``n_r``."""
        from hapticopt.analysis.prrr.geometry import workspace  # noqa: PLC0415

        key = ("workspace_core", tuple(float(v) for v in wp), n_phi)
        cores = self._step(design, key, dict)  # n_r -> core, for this wp and n_phi
        if n_r not in cores:
            cores[n_r] = workspace.workspace_core(wp, n_phi=n_phi, n_r=n_r, xp=np)
        return cores[n_r]

    def reach_core(self, design: PrrrDesign, wp: Any, *, n_phi: int, n_r: int) -> dict:
        """A :meth:`workspace_core` of ``wp`` at ``n_phi`` for a caller that reads only the entries
        that do not depend on the radial sampling ``n_r`` (``reach_radius``, ``empty``,
        ``footprint_diameter``: from the rays and the closed forms, the same operations for every
        ``n_r``, tested bitwise equal): the core already computed for another ``n_r`` if there is
        one, else the one at ``n_r``."""
        key = ("workspace_core", tuple(float(v) for v in wp), n_phi)
        cores = self._step(design, key, dict)
        return next(iter(cores.values())) if cores else self.workspace_core(design, wp, n_phi=n_phi, n_r=n_r)
