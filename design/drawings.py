"""Dimensioned 2-D drawings of manufactured parts (SVG and DXF), for a workshop.

One drawing per distinct part geometry (the three legs' identical parts share one, with their
names and quantity): three orthographic views in the part's own frame — top (looking down −z), front
(looking along +y) and side (looking along −x), third-angle layout, 1:1 in millimetres, visible edges
solid and hidden edges dashed (build123d's hidden-line projection, ``project_to_viewport``) — the
overall dimensions x, y, z as dimension lines (build123d ``ExtensionLine``), and a title block with
the part name(s), quantity, material (design/materials.toml), mass and overall size. Written with
build123d's ``ExportSVG`` and ``ExportDXF``; the SVG also carries the title block as text in its
``<desc>`` element (its drawn text is outlines).

Parts that name no material (catalogue parts: motors, screws, spring housings) get no drawing.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

#: view name -> (direction from the part towards the viewer, up) in the part frame
VIEWS = {"top": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)), "front": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
         "side": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))}


@dataclass(frozen=True, kw_only=True)
class Drawing:
    """What one drawing shows: its parts, material, mass of one [kg] and overall size [mm] (x, y, z of
    the part frame, measured from the projected views)."""

    name: str
    parts: tuple[str, ...]
    material: str
    mass_kg: float
    overall_mm: tuple[float, float, float]

    def title(self) -> str:
        qty = f"qty {len(self.parts)}: {', '.join(self.parts)}" if len(self.parts) > 1 else "qty 1"
        x, y, z = self.overall_mm
        return (f"{self.name} ({qty}) | material {self.material} | mass {self.mass_kg * 1e3:.1f} g each | "
                f"overall {x:.2f} x {y:.2f} x {z:.2f} mm | 1:1, mm, third angle")


def _box2d(edges) -> tuple[float, float, float, float]:
    from build123d import Compound

    bb = Compound(children=list(edges)).bounding_box()
    return bb.min.X, bb.min.Y, bb.max.X, bb.max.Y


def draw(solid: Any, drawing_name: str, parts: tuple[str, ...], material: str, mass_kg: float,
         svg_path: Path, dxf_path: Path) -> Drawing:
    """Write the drawing of ``solid`` (a build123d solid in its part frame, mm) to ``svg_path`` and
    ``dxf_path``; return what it shows."""
    from build123d import Draft, ExportDXF, ExportSVG, ExtensionLine, LineType, Pos, Text

    bb = solid.bounding_box()
    c = (bb.center().X, bb.center().Y, bb.center().Z)
    far = 10.0 * max(bb.size.X, bb.size.Y, bb.size.Z, 1.0)
    proj = {}
    for name, (d, up) in VIEWS.items():
        vis, hid = solid.project_to_viewport(tuple(c[k] + far * d[k] for k in range(3)), up, tuple(c))
        proj[name] = (list(vis), list(hid), _box2d(vis))
    gap = 0.25 * max(bb.size.X, bb.size.Y, bb.size.Z) + 25.0
    fx0, fy0, fx1, fy1 = proj["front"][2]
    tx0, ty0, tx1, ty1 = proj["top"][2]
    sx0, sy0, sx1, sy1 = proj["side"][2]
    # front at the origin, top above it (x aligned), side to its right (z aligned)
    shift = {"front": (-fx0, -fy0), "top": (-tx0 + 0.0, (fy1 - fy0) + gap - ty0), "side": ((fx1 - fx0) + gap - sx0, -sy0)}
    overall = (fx1 - fx0, ty1 - ty0, fy1 - fy0)  # x (front width), y (top height), z (front height)
    draft = Draft(font_size=3.5, decimal_precision=2, display_units=False)
    W, H, Dp = overall
    dims = [ExtensionLine(border=[(0.0, 0.0), (W, 0.0)], offset=8.0, draft=draft),  # x under the front view
            ExtensionLine(border=[(0.0, 0.0), (0.0, Dp)], offset=-8.0, draft=draft),  # z left of the front view
            ExtensionLine(border=[(0.0, Dp + gap), (0.0, Dp + gap + H)], offset=-8.0, draft=draft)]  # y left of the top
    info = Drawing(name=drawing_name, parts=parts, material=material, mass_kg=mass_kg,
                   overall_mm=tuple(round(v, 6) for v in overall))
    lines = info.title().split(" | ")
    block = [Pos(0.0, -20.0 - 5.0 * k) * Text(line, font_size=3.5, align=None) for k, line in enumerate(lines)]
    for writer_cls, path in ((ExportSVG, svg_path), (ExportDXF, dxf_path)):
        if writer_cls is ExportSVG:
            w = ExportSVG(margin=5.0)
            w.add_layer("visible", line_weight=0.35)
            w.add_layer("hidden", line_weight=0.18, line_type=LineType.ISO_DASH)
            w.add_layer("dimensions", line_weight=0.18, fill_color=(0, 0, 0))
        else:
            w = ExportDXF()
            w.add_layer("visible")
            w.add_layer("hidden", line_type=LineType.ISO_DASH)
            w.add_layer("dimensions")
        for name, (vis, hid, _) in proj.items():
            dx, dy = shift[name]
            w.add_shape([Pos(dx, dy) * e for e in vis], layer="visible")
            if hid:
                w.add_shape([Pos(dx, dy) * e for e in hid], layer="hidden")
        w.add_shape(dims, layer="dimensions")
        w.add_shape(block, layer="dimensions")
        w.write(str(path))
    _describe(svg_path, info.title())
    return info


def _describe(svg_path: Path, text: str) -> None:
    """Put the title block as text into the SVG's ``<desc>`` (searchable; the drawn text is outlines)."""
    s = Path(svg_path).read_text(encoding="utf-8")
    head, sep, rest = s.partition(">")  # the XML declaration or the <svg …> tag
    if head.startswith("<?xml"):
        tag_end = rest.index(">", rest.index("<svg")) + 1
        s = head + sep + rest[:tag_end] + f"<desc>{escape(text)}</desc>" + rest[tag_end:]
    else:
        s = head + sep + f"<desc>{escape(text)}</desc>" + rest
    Path(svg_path).write_text(s, encoding="utf-8")


def groups(specs: dict[str, Any]) -> dict[str, tuple[str, ...]]:
    """Drawing name -> the parts it shows: parts that name a material, those with the same primitives
    (the legs' copies) on one drawing, named after the first with its leg suffix dropped."""
    out: dict[int, list[str]] = {}
    for name, spec in specs.items():
        if getattr(spec, "material", ""):
            out.setdefault(id(spec.primitives), []).append(name)
    named = {}
    for names in out.values():
        base = names[0].rsplit("_", 1)[0] if len(names) > 1 else names[0]
        named[base] = tuple(names)
    return named
