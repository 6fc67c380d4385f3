"""Load and save design descriptions (TOML, units in the keys) and bundled presets.

This is where design values enter hapticopt, so every check with a user-facing message
happens here or in the design constructors.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Union

from hapticopt.design import bundled
from hapticopt.design.handle import params as handle
from hapticopt.design.master import params as master
from hapticopt.design.prrr import params as prrr
from hapticopt.design.atomic import write_text
from hapticopt.design import tomlsafe
from hapticopt.design.errors import InputFileError, InvalidDesign, short, short_key
from hapticopt.design.paths import check_name
from hapticopt.design.schema import choices, section_from_table, section_to_table, specs

Design = Union[prrr.PrrrDesign, master.MasterDesign, handle.HandleDesign]

_DEVICES: dict[str, type] = {prrr.DEVICE: prrr.PrrrDesign, master.DEVICE: master.MasterDesign,
                             handle.DEVICE: handle.HandleDesign}
_TOP_KEYS = {"name", "device", "description"}
_DESCRIPTION_MAX = 2000


def _section_classes(design_cls: type) -> dict[str, type]:
    hints = {f.name: f.default_factory for f in design_cls.__dataclass_fields__.values()  # type: ignore[attr-defined]
             if f.name in design_cls.SECTIONS}
    return hints


def design_from_dict(data: dict[str, Any], *, source: str = "design") -> Design:
    """Build a design from a TOML-shaped mapping (edge units). Raises :class:`InvalidDesign`."""
    if not isinstance(data, dict):
        raise InvalidDesign(f"{source}: a design must be a table of keys, got {short(data)}")
    device = data.get("device")
    if not isinstance(device, str) or device not in _DEVICES:
        allowed = ", ".join(f'"{d}"' for d in _DEVICES)
        raise InvalidDesign(f"{source}: device = {short(device)} is not a known device: allowed {allowed}")
    cls = _DEVICES[device]
    sections = _section_classes(cls)
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if key in _TOP_KEYS:
            if key == "name":
                kwargs[key] = check_name(value, f"{source}: name", error=InvalidDesign)
            elif key == "description":
                if not isinstance(value, str) or len(value) > _DESCRIPTION_MAX:
                    raise InvalidDesign(f"{source}: description = {short(value)} must be a string of at most "
                                        f"{_DESCRIPTION_MAX} characters")
                kwargs[key] = value
            continue
        if key not in sections:
            allowed = ", ".join(sorted(_TOP_KEYS | set(sections)))
            raise InvalidDesign(f"{source}: {short_key(key)} is not a known key for a {device} design: allowed {allowed}")
        kwargs[key] = section_from_table(sections[key], value, key)
    return cls(**kwargs)


def design_to_dict(design: Design) -> dict[str, Any]:
    """The TOML-shaped mapping of a design (edge units); inverse of :func:`design_from_dict`."""
    out: dict[str, Any] = {"name": design.name, "device": design.device}
    if design.description:
        out["description"] = design.description
    for section in design.SECTIONS:
        out[section] = section_to_table(getattr(design, section))
    return out


def load_design(path: str | Path) -> Design:
    """Load a design TOML file. Raises :class:`InputFileError` or :class:`InvalidDesign`."""
    path = Path(path)
    try:
        is_file = path.is_file()
    except (OSError, ValueError) as exc:  # a name too long, a NUL in the path
        raise InputFileError(f"design file {short(str(path))} cannot be read: {exc}") from None
    if not is_file:
        raise InputFileError(f"design file {short(str(path))} does not exist: give a path to a .toml design or --preset NAME")
    text = tomlsafe.read_text(path, source=f"design file {short(str(path))}")
    data = tomlsafe.loads(text, source=f"design file {short(str(path))}")
    return design_from_dict(data, source=path.name)


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    raise TypeError(f"cannot write {value!r} to TOML")


def dumps(design: Design) -> str:
    """Design as TOML text (edge units, full precision)."""
    data = design_to_dict(design)
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for section, table in data.items():
        if isinstance(table, dict):
            lines.append("")
            lines.append(f"[{section}]")
            lines.extend(f"{k} = {_toml_value(v)}" for k, v in table.items())
    return "\n".join(lines) + "\n"


def save_design(design: Design, path: str | Path) -> None:
    """Write a design TOML file atomically."""
    write_text(path, dumps(design))


# ---------------------------------------------------------------------------- presets
PRESETS = "hapticopt.design.presets"


def preset_names() -> list[str]:
    """Names of the bundled presets."""
    return bundled.names(PRESETS)


def load_preset(name: str) -> Design:
    """Load a bundled preset by name. Raises :class:`UnknownName`."""
    found = bundled.read(PRESETS, "preset", name, allow_path=False)
    return design_from_dict(tomlsafe.loads(found.text, source=found.source), source=found.source)


# ---------------------------------------------------------------------------- overrides
def apply_overrides(design: Design, assignments: list[str]) -> Design:
    """Apply ``section.key=value`` assignments (TOML keys, edge units) to a design."""
    if not assignments:
        return design
    data = design_to_dict(design)
    set_keys: set[tuple[str, str]] = set()
    for assignment in assignments:
        if "=" not in assignment:
            raise InvalidDesign(f"--set {short(assignment)} must have the form section.key=value, e.g. geometry.beta_deg=50")
        lhs, rhs = (s.strip() for s in assignment.split("=", 1))
        if lhs in ("name", "description"):
            data[lhs] = check_name(rhs, "--set name", error=InvalidDesign) if lhs == "name" else rhs
            continue
        if lhs.count(".") != 1:
            raise InvalidDesign(f"--set {short_key(lhs)} must name section.key, e.g. geometry.beta_deg")
        section, key = lhs.split(".")
        if section not in design.SECTIONS:
            raise InvalidDesign(f"--set {short_key(lhs)}: {short_key(section)} is not a section of a {design.device} design: "
                                f"allowed {', '.join(design.SECTIONS)}")
        allowed_keys = {s.key for s in specs(getattr(design, section)).values()}
        allowed_keys |= {c.key for c in choices(getattr(design, section)).values()}
        if key not in allowed_keys:
            raise InvalidDesign(f"--set {short_key(lhs)} is not a known parameter: allowed keys in [{section}] are "
                                f"{', '.join(sorted(allowed_keys))}")
        try:
            value = tomlsafe.loads(f"v = {rhs}", source=f"--set {lhs}")["v"]
        except InputFileError:
            value = rhs  # not a TOML value: checked (and refused as "not a number") below
        data[section][key] = value
        set_keys.add((section, key))
    for section, key in set_keys:  # a choice set here refills what it sets (a material's density and moduli)
        for cspec in choices(getattr(design, section)).values():
            if cspec.key == key and cspec.fills is not None:
                sec_specs = specs(getattr(design, section))
                for fname in cspec.fills(data[section][key]):
                    fkey = sec_specs[fname].key
                    if (section, fkey) not in set_keys:
                        data[section].pop(fkey, None)
    return design_from_dict(data, source="--set")
