"""User documentation stands on its own: no issue-tracker numbers and no files outside the repository."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).parents[1]
FORBIDDEN = [(re.compile(r"\bissues? #?\d+", re.I), "an issue number"), (re.compile(r"\.\./shared"), "../shared"),
             (re.compile(r"seed[ -]digest", re.I), "the seed digest (not in the repository)")]


def documents() -> list[Path]:
    return sorted(ROOT.joinpath("docs").rglob("*.md")) + [ROOT / "README.md"]


def scan(text: str) -> list[str]:
    return [f"line {text.count(chr(10), 0, m.start()) + 1}: {what} ({m.group(0)!r})"
            for pattern, what in FORBIDDEN for m in pattern.finditer(text)]


def test_docs_and_readme_cite_no_issue_numbers_and_no_outside_files():
    found = {str(p.relative_to(ROOT)): scan(p.read_text(encoding="utf-8")) for p in documents()}
    assert len(found) > 10  # docs/ exists and is read
    assert {k: v for k, v in found.items() if v} == {}


def test_the_scan_sees_each_pattern():
    assert len(scan("see issue 4, Issue 15 and issues #20\nthe ../shared/docs/seed-digest.md")) == 5


def test_references_cite_the_four_papers_by_title():
    text = (ROOT / "docs" / "references.md").read_text(encoding="utf-8")
    for title in ("Stability analysis of VE force feedback interaction system based on haptic handle",
                  "Human-robot physical interaction control method based on iterative optimal impedance",
                  "A Parallel Robot for Large-range Stiffness Rendering in Three Dimensions",
                  "Study on the Gravity Imbalance of Haptic Master of Surgical Robot"):
        assert title in text, title
