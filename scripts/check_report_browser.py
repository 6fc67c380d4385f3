"""Open DIR/report.html in headless Chromium and check that it loads without errors, images
included, and that nothing overflows the page sideways.

Usage: python scripts/check_report_browser.py RUN_DIR [SCREENSHOT.png]
(exit 0: ok; 1: a problem, printed one per line; with SCREENSHOT.png also a full-page screenshot)

How: a loopback HTTP server serves RUN_DIR plus a checker page that loads report.html in an
iframe (same origin, ``WIDTH`` px wide), waits for it, and writes into its own DOM, for every
<img>, whether it loaded (``complete`` and ``naturalWidth > 0``), any script error caught in the
report, the report's ``scrollWidth`` against its ``clientWidth`` (horizontal overflow) and the
elements that stick out on the right. Chromium's ``--dump-dom`` prints that DOM. Every request
the server answers with an error status (a broken link) is a failure too, as is a console error
in Chromium's log. Needs Debian's ``chromium`` (``apt-get install chromium``).
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
<iframe id="f" src="report.html" width="WIDTH" height="900" style="border:0"></iframe>
<script>
const out = document.getElementById('result');
const frame = document.getElementById('f');
frame.addEventListener('load', () => {
  const doc = frame.contentDocument;
  const errors = [];
  const imgs = Array.from(doc.images);
  const wait = imgs.map(img => img.complete ? Promise.resolve() :
      new Promise(r => { img.addEventListener('load', r); img.addEventListener('error', r); }));
  Promise.all(wait).then(() => {
    const root = doc.documentElement;
    const wide = Array.from(doc.body.querySelectorAll('*')).filter(
        el => el.getBoundingClientRect().right > root.clientWidth + 0.5).map(
        el => el.tagName.toLowerCase() + (el.getAttribute('src') ? '[' + el.getAttribute('src') + ']' : '')
              + ' right=' + Math.round(el.getBoundingClientRect().right));
    (frame.contentWindow.__problems || ['the probe script did not run']).forEach(e => errors.push(e));
    const res = {title: doc.title, tables: doc.querySelectorAll('table').length, errors: errors,
      scrollWidth: root.scrollWidth, clientWidth: root.clientWidth, scrollHeight: root.scrollHeight, wide: wide.slice(0, 5),
      images: imgs.map(i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0}))};
    out.textContent = 'RESULT:' + JSON.stringify(res) + ':END';
  });
});
</script></body></html>"""


#: put first into the served report (never into the file): records console errors and warnings,
#: uncaught exceptions and resources that failed to load, for the checker page to read
PROBE = """<script>window.__problems = [];
(function () {
  const keep = (kind) => { const orig = console[kind]; console[kind] = function (...a) {
    window.__problems.push('console.' + kind + ': ' + a.map(String).join(' ')); return orig.apply(console, a); }; };
  keep('error'); keep('warn');
  window.addEventListener('error', (e) => { window.__problems.push(e.target && e.target !== window
      ? 'resource failed: ' + (e.target.getAttribute('src') || e.target.getAttribute('href'))
      : 'uncaught: ' + e.message); }, true);
})();</script>"""


def find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def check(run_dir: Path, *, width: int = 1200, timeout_s: float = 60.0, screenshot: Path | None = None) -> list[str]:
    """Problems found (empty: the report loaded cleanly with every image and no horizontal overflow
    in a ``width`` px wide window). ``screenshot``: also write a full-page PNG of the report there."""
    run_dir = Path(run_dir).resolve()
    if not (run_dir / "report.html").is_file():
        return [f"{run_dir}/report.html does not exist"]
    chromium = find_chromium()
    if chromium is None:
        return ["chromium is not installed (apt-get install chromium)"]
    failures: list[str] = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def _send_html(self, body: bytes) -> None:
            self.send_response(200)
            self.send_header("Content-Type", "text/html; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self) -> None:  # noqa: N802 - http.server API
            if self.path.startswith("/__check__.html"):
                self._send_html(CHECKER.replace("WIDTH", str(int(width))).encode())
            elif self.path.split("?")[0] == "/report.html":  # the report with the probe put first
                text = (run_dir / "report.html").read_text(encoding="utf-8")
                head = text.find("<head>")
                at = head + len("<head>") if head >= 0 else 0
                self._send_html((text[:at] + PROBE + text[at:]).encode())
            else:
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
    base = f"http://127.0.0.1:{server.server_address[1]}"
    flags = [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--hide-scrollbars",
             "--disable-dev-shm-usage", "--virtual-time-budget=10000", "--enable-logging=stderr", "--v=0"]
    try:
        proc = subprocess.run(flags + ["--dump-dom", f"{base}/__check__.html"], capture_output=True, text=True,
                              timeout=timeout_s)
        if screenshot is not None:
            height = _page_height(proc.stdout)
            shot = subprocess.run(flags + [f"--screenshot={Path(screenshot).resolve()}",
                                           f"--window-size={int(width)},{height}", f"{base}/report.html"],
                                  capture_output=True, text=True, timeout=timeout_s)
            if shot.returncode != 0 or not Path(screenshot).is_file():
                failures.append(f"no screenshot (chromium exit {shot.returncode})")
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
    failures += [f"script error: {e}" for e in result["errors"] if not e.startswith("resource failed")]
    if result["tables"] == 0:
        failures.append("the report has no tables")
    if result["scrollWidth"] > result["clientWidth"]:
        failures.append(f"horizontal overflow: the page is {result['scrollWidth']} px wide in a "
                        f"{result['clientWidth']} px window ({'; '.join(result['wide'])})")
    failures += [f"console: {line.strip()}" for line in proc.stderr.splitlines()
                 if "CONSOLE" in line and ("Uncaught" in line or "rror" in line)]
    return failures


def _page_height(dom: str) -> int:
    """The report's height [px] as the checker page measured it (a full-page screenshot), at most 30000."""
    m = re.search(r'"scrollHeight":(\d+)', dom)
    return min(30000, int(m.group(1)) + 20) if m else 6000


def main(argv: list[str]) -> int:
    if len(argv) not in (1, 2):
        print(__doc__.strip().splitlines()[3], file=sys.stderr)
        return 2
    problems = check(Path(argv[0]), screenshot=Path(argv[1]) if len(argv) == 2 else None)
    for p in problems:
        print(p)
    if not problems:
        print(f"ok: {argv[0]}/report.html loaded in headless Chromium with all images")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
