"""Helpers to kill a pipeline process at a moment and check what it leaves (tests and
scripts/kill_resume.py)."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

DATA = Path(__file__).parent / "data"
SCRIPT = DATA / "pipeline_run.py"


def env() -> dict[str, str]:
    path = os.pathsep.join([str(DATA)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
    return {**os.environ, "PYTHONPATH": path, "PYTHONWARNINGS": "ignore"}


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            children.setdefault(ppid, []).append(int(entry))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")  # a zombie has exited (its parent is gone)


def start(run_dir: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(SCRIPT), str(run_dir), *args], env=env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def kill_after(proc: subprocess.Popen, delay_s: float) -> tuple[bool, set[int], float]:
    """SIGKILL ``proc`` ``delay_s`` after now (unless it ends first). Returns (killed, the children
    it had, seconds until they were all gone; inf if some outlived 5 s)."""
    deadline = time.monotonic() + delay_s
    kids: set[int] = set()
    while time.monotonic() < deadline and proc.poll() is None:
        kids |= descendants(proc.pid)
        time.sleep(0.05)
    if proc.poll() is not None:
        return False, kids, 0.0
    kids |= descendants(proc.pid)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    t0 = time.monotonic()
    while any(alive(k) for k in kids):
        if time.monotonic() - t0 > 5.0:
            return True, kids, float("inf")
        time.sleep(0.05)
    return True, kids, time.monotonic() - t0


def recorded(run_dir: Path) -> tuple[int, int]:
    """(evaluations, recorded stages) in the run database (0, 0 when it does not exist yet)."""
    db_path = run_dir / "evaluations.sqlite"
    if not db_path.exists():
        return 0, 0
    with sqlite3.connect(db_path, timeout=10) as db:
        tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        n = db.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0] if "evaluations" in tables else 0
        s = db.execute("SELECT COUNT(*) FROM stages").fetchone()[0] if "stages" in tables else 0
    db.close()
    return n, s


def leftovers(run_dir: Path) -> list[Path]:
    """Temporary files and staging folders left in the run directory."""
    return [p for p in run_dir.rglob(".*") if p.name != ".hapticopt.lock"]
