"""docs/problems.md documents every key of a problem file, and only those (optim/problem.py TABLE_KEYS)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from hapticopt.optim.problem import PROBLEM_NAME_MAX, TABLE_KEYS, OptimiserConfig

DOC = Path(__file__).parents[2] / "docs" / "problems.md"
HEADINGS = {"Top level": [""], "`[[variables]]`": ["variables"], "`[objective]` and `[[objectives]]`":
            ["objective", "objectives"], "`[[constraints]]`": ["constraints"], "`[optimiser]`": ["optimiser"],
            "`[fidelity]`": ["fidelity"], "`[verify]`": ["verify"], "`[pareto]`": ["pareto"]}


def documented() -> dict[str, set[str]]:
    """Table heading -> the keys in the first column of its table."""
    out: dict[str, set[str]] = {}
    heading = None
    for line in DOC.read_text().splitlines():
        if line.startswith("## "):
            heading = line[3:].strip()
            out[heading] = set()
        elif heading is not None and (m := re.match(r"^\| `([a-z_]+)` \|", line)):
            out[heading].add(m.group(1))
    return out


def test_every_table_and_key_is_documented_and_nothing_else():
    docs = documented()
    assert set(docs) == set(HEADINGS)
    for heading, tables in HEADINGS.items():
        for table in tables:
            assert docs[heading] == set(TABLE_KEYS[table]), heading


def test_table_keys_cover_the_loader():
    assert set(TABLE_KEYS) == {""} | {k for k in TABLE_KEYS[""] if k not in ("name", "description", "device", "base",
                                                                            "base_file")}
    assert TABLE_KEYS["optimiser"] == {f.name for f in dataclasses.fields(OptimiserConfig)}


def test_the_name_limit_in_the_doc_is_the_loaders():
    assert f"1–{PROBLEM_NAME_MAX} characters" in DOC.read_text()


def test_the_checker_sees_an_undocumented_key(tmp_path, monkeypatch):
    """A key the loader accepts but the doc lacks fails the comparison."""
    extended = dict(TABLE_KEYS, verify=TABLE_KEYS["verify"] | {"new_key"})
    assert documented()["`[verify]`"] != set(extended["verify"])
