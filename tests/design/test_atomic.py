"""File sets written as one (issue 14: an export to a full disk left 14 of 18 files)."""

from __future__ import annotations

import errno

import pytest

from hapticopt.design import atomic


def _old_set(root):
    atomic.write_text(root / "a.txt", "old a")
    atomic.write_text(root / "parts" / "b.txt", "old b")


def _contents(root):
    return {p.relative_to(root).as_posix(): p.read_text() for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_file_set_is_moved_in_whole(tmp_path):
    _old_set(tmp_path)
    with atomic.file_set(tmp_path) as stage:
        atomic.write_text(stage / "a.txt", "new a")
        atomic.write_text(stage / "parts" / "b.txt", "new b")
        atomic.write_text(stage / "parts" / "c.txt", "new c")
        assert _contents(tmp_path)["a.txt"] == "old a"  # nothing visible before the end
    assert _contents(tmp_path) == {"a.txt": "new a", "parts/b.txt": "new b", "parts/c.txt": "new c"}


@pytest.mark.parametrize("fail_after", [0, 1, 2])
def test_a_fault_while_writing_leaves_the_old_set_and_no_staging(tmp_path, fail_after):
    _old_set(tmp_path)
    before = _contents(tmp_path)
    with pytest.raises(OSError, match="No space left"):
        with atomic.file_set(tmp_path) as stage:
            for i, name in enumerate(("a.txt", "parts/b.txt", "parts/c.txt")):
                if i == fail_after:
                    raise OSError(errno.ENOSPC, "No space left on device", str(stage / name))
                atomic.write_text(stage / name, "new")
    assert _contents(tmp_path) == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_stale_staging_folders_are_removed(tmp_path):
    cm = atomic.file_set(tmp_path)
    stage = cm.__enter__()  # a process killed here leaves its staging folder behind
    atomic.write_text(stage / "x.txt", "partial")
    assert atomic.remove_stale_temp_files(tmp_path) == [stage]
    assert list(tmp_path.iterdir()) == []
