"""Open DIR/report.html in headless Chromium and check that it loads without errors, images included.

Usage: python scripts/check_report_browser.py RUN_DIR  (exit 0: ok; 1: a problem, printed one per line)

How: a loopback HTTP server serves RUN_DIR plus a checker page that loads report.html in an
iframe (same origin), waits for it, and writes into its own DOM, for every <img>, whether it
loaded (``complete`` and ``naturalWidth > 0``), plus any script error caught in the report.
Chromium's ``--dump-dom`` prints that DOM. Every request the server answers with an error
status (a broken link) is a failure too, as is a console error in Chromium's log.
Needs Debian's ``chromium`` (``apt-get install chromium``).
"""

from __future__ import annotations

import functools
import http.server
import json
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

CHECKER = """<!DOCTYPE html><html><head><meta charset="utf-8"></head><body>
<pre id="result">pending</pre>
<iframe id="f" src="report.html" width="1200" height="900"></iframe>
<script>
const out = document.getElementById('result');
const frame = document.getElementById('f');
frame.addEventListener('load', () => {
  const doc = frame.contentDocument;
  const errors = [];
  frame.contentWindow.addEventListener('error', e => errors.push(String(e.message)));
  const imgs = Array.from(doc.images);
  const wait = imgs.map(img => img.complete ? Promise.resolve() :
      new Promise(r => { img.addEventListener('load', r); img.addEventListener('error', r); }));
  Promise.all(wait).then(() => {
    const res = {title: doc.title, tables: doc.querySelectorAll('table').length, errors: errors,
      images: imgs.map(i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0}))};
    out.textContent = 'RESULT:' + JSON.stringify(res) + ':END';
  });
});
</script></body></html>"""


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def check(run_dir: Path, *, timeout_s: float = 60.0) -> list[str]:
    """Problems found (empty: the report loaded cleanly with every image)."""
    run_dir = Path(run_dir).resolve()
    if not (run_dir / "report.html").is_file():
        return [f"{run_dir}/report.html does not exist"]
    chromium = find_chromium()
    if chromium is None:
        return ["chromium is not installed (apt-get install chromium)"]
    failures: list[str] = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - http.server API
            if self.path.startswith("/__check__.html"):
                body = CHECKER.encode()
                self.send_response(200)
                self.send_header("Content-Type", "text/html; charset=utf-8")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)
                return
            super().do_GET()

        def log_request(self, code: int | str = "-", size: int | str = "-") -> None:
            if isinstance(code, int) or str(code).isdigit():
                if int(code) >= 400 and not self.path.startswith("/favicon"):
                    failures.append(f"HTTP {code} for {self.path}")

        def log_message(self, format: str, *args: object) -> None:  # noqa: A002
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Handler, directory=str(run_dir)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    url = f"http://127.0.0.1:{server.server_address[1]}/__check__.html"
    try:
        proc = subprocess.run([chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                               "--disable-dev-shm-usage", "--virtual-time-budget=10000", "--enable-logging=stderr",
                               "--v=0", "--dump-dom", url], capture_output=True, text=True, timeout=timeout_s)
    finally:
        server.shutdown()
        server.server_close()
    m = re.search(r"RESULT:(.*?):END", proc.stdout, re.S)
    if m is None:
        return failures + [f"the checker page did not finish (chromium exit {proc.returncode}): "
                           f"{proc.stderr.strip().splitlines()[-1:] or ''}"]
    result = json.loads(m.group(1).replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">"))
    if not result["images"]:
        failures.append("the report has no images")
    failures += [f"image did not load: {img['src']}" for img in result["images"] if not img["ok"]]
    failures += [f"script error: {e}" for e in result["errors"]]
    if result["tables"] == 0:
        failures.append("the report has no tables")
    failures += [f"console: {line.strip()}" for line in proc.stderr.splitlines()
                 if "CONSOLE" in line and ("Uncaught" in line or "rror" in line)]
    return failures


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    problems = check(Path(argv[0]))
    for p in problems:
        print(p)
    if not problems:
        print(f"ok: {argv[0]}/report.html loaded in headless Chromium with all images")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
