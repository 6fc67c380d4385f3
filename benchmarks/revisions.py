"""An older revision's module loaded beside this tree's, for the side-by-side ``ratio_*_rev`` scripts."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def module_from(rev: str, path: str, name: str, **inject) -> types.ModuleType:
    """The file ``path`` of git revision ``rev`` executed as a module named ``name`` (registered in
    ``sys.modules``), then the names ``inject`` bound in it (e.g. the old revision's own dependencies)."""
    src = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, check=True, capture_output=True, text=True).stdout
    mod = types.ModuleType(name)
    mod.__dict__["__name__"] = name
    sys.modules[name] = mod
    exec(compile(src, f"{rev}:{path}", "exec"), mod.__dict__)
    mod.__dict__.update(inject)
    return mod
