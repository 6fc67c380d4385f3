"""Regenerate docs/metrics.md from the registry's metric descriptions.

    PYTHONPATH=… python scripts/gen_metrics_doc.py     # writes docs/metrics.md
    python scripts/gen_metrics_doc.py --check          # exit 1 if docs/metrics.md is stale
"""

from __future__ import annotations

import sys
from pathlib import Path

from hapticopt.design.atomic import write_text
from hapticopt.optim.cli.metrics import markdown

DOC = Path(__file__).resolve().parents[1] / "docs" / "metrics.md"


def main(argv: list[str]) -> int:
    text = markdown()
    if "--check" in argv:
        stale = not DOC.is_file() or DOC.read_text(encoding="utf-8") != text
        print(f"{DOC} is {'stale: run scripts/gen_metrics_doc.py' if stale else 'up to date'}")
        return 1 if stale else 0
    write_text(DOC, text)
    print(f"wrote {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
