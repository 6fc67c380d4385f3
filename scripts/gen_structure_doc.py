"""Regenerate docs/structure.md's prrr-paper table (home pose, frame model) from the frame model.

    python scripts/gen_structure_doc.py            # rewrites the table between its markers
    python scripts/gen_structure_doc.py --check    # exit 1 if the table is stale

Rows: lateral and axial stiffness at the load height Δz = 58 mm, the elastic centre and the stiffness
there, for the default frame (released joints with necks) on the elbow branch the device is assembled
in (the CAD's, design.prrr.cad.DEFAULT_BRANCH = 1, the frame model's default), the same frame on the
other branch (branch 0: its link2 collide under the platform, docs/cad.md), and the plane frame
(``pins=False``) on the default branch; beside seed 002 Table 3 (ANSYS / experiment).
"""

from __future__ import annotations

import sys
from pathlib import Path

from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.prrr.structure.stiffness import structural_stiffness
from hapticopt.design import io
from hapticopt.design.atomic import write_text
from hapticopt.design.prrr.cad import DEFAULT_BRANCH

DOC = Path(__file__).resolve().parents[1] / "docs" / "structure.md"
BEGIN, END = "<!-- prrr-paper-frame:begin (scripts/gen_structure_doc.py) -->", "<!-- prrr-paper-frame:end -->"
#: seed 002 Table 3 (N/mm, end-effector at the origin): ANSYS / experiment at Δz = 58 mm; ANSYS at the elastic centre
PAPER = ("37.66, 37.66, 243.79 / 36.82, 36.50, 201.51", "17.5", "42.25, 42.25, –")


def _cols(options: fm.FrameOptions) -> tuple[str, str, str]:
    r = structural_stiffness(io.load_preset("prrr-paper"), options=options)
    k = ", ".join(f"{v * 1e-3:.1f}" for v in r.stiffness_load)
    kc = ", ".join(f"{v * 1e-3:.1f}" for v in r.stiffness_elastic_centre)
    return k, f"{r.elastic_centre * 1e3:+.1f}", kc


def table() -> str:
    other = 1 - DEFAULT_BRANCH
    cols = [_cols(fm.FrameOptions()), _cols(fm.FrameOptions(branch=other)), _cols(fm.FrameOptions(pins=False))]
    head = (f"| quantity | frame (default: necks, branch {DEFAULT_BRANCH}, the CAD's) | frame on branch {other} "
            f"(not the assembled one) | plane frame (`pins=False`, branch {DEFAULT_BRANCH}) | "
            "seed 002 Table 3 (ANSYS / exp.; no sections given) |")
    rows = [head, "|---|---|---|---|---|"]
    for i, name in enumerate(("k at Δz = 58 mm [N/mm]", "elastic centre above the end-effector [mm]",
                              "k at elastic centre [N/mm]")):
        rows.append(f"| {name} | {cols[0][i]} | {cols[1][i]} | {cols[2][i]} | {PAPER[i]} |")
    return "\n".join(rows)


def render(text: str) -> str:
    start, stop = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[:start] + "\n" + table() + "\n" + text[stop:]


def main(argv: list[str]) -> int:
    text = DOC.read_text(encoding="utf-8")
    new = render(text)
    if "--check" in argv:
        stale = new != text
        print(f"{DOC} is {'stale: run scripts/gen_structure_doc.py' if stale else 'up to date'}")
        return 1 if stale else 0
    write_text(DOC, new)
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
