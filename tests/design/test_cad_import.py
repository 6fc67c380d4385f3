"""build123d imported without scikit-learn (design/cad_import.py), in a fresh interpreter each."""

import subprocess
import sys

_CHECK = """
import sys
from hapticopt.design import cad_import
build123d = cad_import.build123d()
from build123d import Box
assert "sklearn" not in sys.modules, "scikit-learn was imported with build123d"
assert Box(1, 1, 1).volume > 0.999
real = build123d.brep_from_stl.FaceSample  # any name of the module: the real one is imported now
assert "sklearn" in sys.modules and real.__module__ == "build123d.brep_from_stl"
import build123d.brep_from_stl as m
assert not isinstance(m, cad_import._StandIn) and build123d.brep_from_stl is m
print("ok")
"""

_AFTER = """
import sys
import build123d
from hapticopt.design import cad_import
assert cad_import.build123d() is build123d  # too late to defer: the real module stays
assert "sklearn" in sys.modules and not isinstance(sys.modules[cad_import.DEFERRED], cad_import._StandIn)
print("ok")
"""


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_build123d_imports_without_scikit_learn_until_used():
    done = _run(_CHECK)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_after_a_plain_import_nothing_changes():
    done = _run(_AFTER)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"
