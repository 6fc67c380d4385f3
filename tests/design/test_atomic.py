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


def test_a_set_killed_while_moving_in_is_completed_by_the_next_cleanup(tmp_path):
    """Issue 37: moving the report set into place was not atomic against a kill. A staging folder with the
    completion marker is moved in (rolled forward); one without it (killed while writing) is removed."""
    from hapticopt.design.atomic import COMPLETE, remove_stale_temp_files

    (tmp_path / "report.md").write_text("old")
    (tmp_path / "result.json").write_text("old")
    done = tmp_path / ".set.abc123.tmp"
    done.mkdir()
    (done / "result.json").write_text("new")  # report.md was already moved in when the kill came
    (done / COMPLETE).write_text("")
    (tmp_path / "report.md").write_text("new")
    partial = tmp_path / ".set.def456.tmp"
    partial.mkdir()
    (partial / "report.md").write_text("half")
    remove_stale_temp_files(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.md", "result.json"]
    assert (tmp_path / "report.md").read_text() == "new" and (tmp_path / "result.json").read_text() == "new"


def test_a_link_below_the_root_of_a_file_set_is_refused(tmp_path):
    from hapticopt.design.atomic import file_set
    from hapticopt.design.errors import InputFileError

    outside = tmp_path / "outside"
    outside.mkdir()
    root = tmp_path / "root"
    root.mkdir()
    (root / "parts").symlink_to(outside, target_is_directory=True)
    with pytest.raises(InputFileError, match="symbolic link"):
        with file_set(root) as stage:
            (stage / "parts").mkdir()
            (stage / "parts" / "a.stl").write_text("x")
    assert list(outside.iterdir()) == [] and sorted(p.name for p in root.iterdir()) == ["parts"]
