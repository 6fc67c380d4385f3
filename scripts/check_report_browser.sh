#!/bin/sh
# Open RUN_DIR/report.html in headless Chromium (Debian package `chromium`) and check that it
# loads without errors and that every image loads. Usage: scripts/check_report_browser.sh cad_out/prrr-workspace
set -e
HERE=$(dirname "$0")
PY=${PYTHON:-$HERE/../.venv/bin/python}
exec "$PY" "$HERE/check_report_browser.py" "${1:-cad_out/prrr-workspace}"
