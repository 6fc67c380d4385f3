"""Closed-loop verification of any device: the firmware against the plant a scene calls for.

:func:`simulate` asks the resolver (:func:`hapticopt.analysis.loop.scene.resolve`) which plant
models the scene's effects and runs it: the 3-PRRR's lumped SEA plant fused with its firmware
(:func:`hapticopt.analysis.prrr.loop.closed_loop.simulate_lumped`), the 3-PRRR's MuJoCo plant
(:func:`hapticopt.analysis.prrr.loop.mujoco_plant.simulate`) or the master's MuJoCo plant
(:func:`hapticopt.analysis.master.mujoco_plant.simulate`), or seed 000's handle
(:func:`hapticopt.analysis.handle.closed_loop.simulate`). Scenes in the IOIC firmware mode
(``controller.mode = "ioic"``, seed 001) run the device's IOIC firmware instead: the master's
IOIC + NTSMTC on its MuJoCo plant (:func:`hapticopt.analysis.master.ioic.simulate`), the 3-PRRR's
IOIC over its SEA force loops on the lumped plant (:func:`hapticopt.analysis.prrr.loop.ioic.simulate`).
Every result's metrics name the backend and the reason (``backend``, ``backend_reason``). ``compute`` chooses
the MuJoCo plants' tick loop (compiled or Python: the same records); the other plants have one route.
"""

from __future__ import annotations

from typing import Any

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.handle import closed_loop as handle_loop
from hapticopt.analysis.loop.scene import Backend, FirmwareMode, Scene, resolve
from hapticopt.design.errors import InvalidInput
from hapticopt.analysis.prrr.loop import closed_loop
from hapticopt.analysis.master import mujoco_plant as master_mujoco
from hapticopt.analysis.prrr.loop import mujoco_plant as prrr_mujoco
def simulate(design: Any, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD,
             backend: Backend | None = None, compute: Compute = DEFAULT) -> Any:
    """Run ``scene`` on ``design`` on the backend the resolver picks (or ``backend`` forces)."""
    res = resolve(scene, force=backend)
    if scene.device == "handle":
        return handle_loop.simulate(design, scene, fidelity=fidelity)
    if scene.controller.mode == FirmwareMode.IOIC:
        if scene.device == "master":
            from hapticopt.analysis.master import ioic as master_ioic

            return master_ioic.simulate(design, scene, fidelity=fidelity, reason=res.reason)
        if res.backend != Backend.LUMPED:
            raise InvalidInput(f"scene {scene.name}: the 3-PRRR's IOIC mode runs on the lumped plant: allowed "
                               "--backend auto or lumped")
        from hapticopt.analysis.prrr.loop import ioic as prrr_ioic
        return prrr_ioic.simulate(design, scene, fidelity=fidelity)
    if scene.device == "master":
        return master_mujoco.simulate(design, scene, fidelity=fidelity, reason=res.reason, compute=compute)
    if res.backend == Backend.MULTIBODY:
        return prrr_mujoco.simulate(design, scene, fidelity=fidelity, reason=res.reason, compute=compute)

    return closed_loop.simulate_lumped(design, scene, fidelity=fidelity)
