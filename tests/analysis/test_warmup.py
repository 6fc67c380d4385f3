"""The setup-time warm-up (analysis/warmup.py) compiles or loads every numba kernel and says so."""

from hapticopt.analysis import warmup
from hapticopt.analysis.loop import mujoco_compiled
from hapticopt.analysis.prrr.structure import frame_condense
from hapticopt.analysis.prrr.collision import interference_fast
def test_warm_reports_each_kernel_and_its_state(capsys):
    rows = warmup.warm()
    assert [name for name, _, _ in rows] == ["collision check", "MuJoCo closed loops", "frame condensation"]
    # each row's state is the kernel's own availability (None: compiled and ready here)
    assert rows[0][1] == interference_fast.availability()
    assert rows[1][1] == mujoco_compiled.availability()
    assert rows[2][1] == frame_condense.kernel_availability()
    assert all(seconds >= 0.0 for _, _, seconds in rows)
    warmup.main()
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3 and all(line.startswith("warm-up: ") for line in lines)
    for line, (_, reason, _) in zip(lines, rows):
        assert ("ready" in line) == (reason is None)
