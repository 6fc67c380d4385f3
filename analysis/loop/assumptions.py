"""The values a seed experiment's scene must assume because the paper does not give them.

A scene that replicates a seed experiment (its ``[report]`` table) names every such value in
``[[report.assumptions]]``: the key it sets and the source of the number (why this value). The verify
output lists them (``assumptions``: key, value, source) with the value the run actually used, read from
the scene after any ``--period-ms`` / ``--force-gain`` override and from the design (``design.<section>.<key>``),
so the list cannot go stale against the numbers it describes.

Keys (:data:`SCENE_KEYS` of the scene, in the scene TOML's units; ``design.<section>.<key>`` of the design TOML).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from hapticopt.design import io
from hapticopt.design.errors import InvalidInput, short

#: scene keys an assumption may name → the value the run uses, in the key's unit
SCENE_KEYS: dict[str, Callable[[Any], Any]] = {
    "controller.period_ms": lambda s: s.controller.period * 1e3,
    "controller.force_gain": lambda s: s.controller.force_gain,
    "controller.velocity_filter_Hz": lambda s: s.controller.velocity_filter,
    "controller.friction_compensation_velocity_mm_per_s": lambda s: s.controller.friction_compensation_velocity * 1e3,
    "operator.mass_kg": lambda s: s.operator.mass,
    "operator.damping_Ns_per_m": lambda s: s.operator.damping,
    "operator.stiffness_N_per_mm": lambda s: s.operator.stiffness * 1e-3,
    "effects.friction_location": lambda s: str(s.friction_location),
    "simulation.output_locked": lambda s: bool(s.output_locked),
}
DESIGN_PREFIX = "design."


@dataclass(frozen=True, kw_only=True)
class Assumption:
    """A value the paper does not give: the key that sets it and the source of the number."""

    key: str
    source: str


def parse(items: Any, where: str) -> tuple[Assumption, ...]:
    """``[[report.assumptions]]`` (a list of tables {key, source}) with one-line errors."""
    if not isinstance(items, list):
        raise InvalidInput(f"{where} = {short(items)} must be a list of tables {{key, source}}")
    out = []
    for i, item in enumerate(items):
        at = f"{where}[{i}]"
        if not isinstance(item, dict) or set(item) != {"key", "source"}:
            raise InvalidInput(f"{at} = {short(item)} must be a table with exactly the keys key and source")
        key, source = item["key"], item["source"]
        if not isinstance(source, str) or not source.strip():
            raise InvalidInput(f"{at}.source = {short(source)} must be a non-empty string (why this value)")
        if not isinstance(key, str) or not (key in SCENE_KEYS or (key.startswith(DESIGN_PREFIX)
                                                                  and key.count(".") == 2)):
            raise InvalidInput(f"{at}.key = {short(key)} is not a key an assumption can name: allowed "
                               + ", ".join(SCENE_KEYS) + ", design.<section>.<key>")
        out.append(Assumption(key=key, source=source))
    return tuple(out)


def values(assumptions: tuple[Assumption, ...], scene: Any, design: Any) -> list[dict[str, Any]]:
    """[{key, value, source}] with the value of each key in this run (scene keys in their TOML unit;
    design keys as the design TOML holds them; None where the design has no such key)."""
    table = io.design_to_dict(design) if any(a.key.startswith(DESIGN_PREFIX) for a in assumptions) else {}
    out = []
    for a in assumptions:
        if a.key.startswith(DESIGN_PREFIX):
            _, section, key = a.key.split(".")
            v = table.get(section, {}).get(key) if isinstance(table.get(section), dict) else None
        else:
            v = SCENE_KEYS[a.key](scene)
        out.append({"key": a.key, "value": v, "source": a.source})
    return out
