#!/usr/bin/env bash
# `make run` of this checkout against an older revision, side by side (interleaved pairs, one machine,
# one hour): the three commands of `make run` from an empty cad_out, each revision imported through a
# package shim so both use this checkout's .venv. Prints one line per pair: the ratio of the whole, each
# command's ratio, and the load average after the pair.
#   usage: benchmarks/make_run_ratio.sh OLD_REVISION [PAIRS]      (e.g. c2550d8 3)
#   HAPTICOPT_PY=/path/to/python: the interpreter (default: this checkout's .venv; a git worktree without
#   its own .venv names the main checkout's)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OLD=${1:?an older revision to compare with}; PAIRS=${2:-3}
PY="${HAPTICOPT_PY:-$ROOT/.venv/bin/python}"
[ -x "$PY" ] || { echo "no Python at $PY: set HAPTICOPT_PY" >&2; exit 2; }
TMP=$(mktemp -d); trap 'git -C "$ROOT" worktree remove --force "$TMP/old" >/dev/null 2>&1 || true; rm -rf "$TMP"' EXIT
git -C "$ROOT" worktree add -q --detach "$TMP/old" "$OLD"
shim() {  # shim DIR SRC: hapticopt.{design,analysis,optim} from SRC
    mkdir -p "$1/hapticopt"; echo '"""shim"""' > "$1/hapticopt/__init__.py"
    for p in design analysis optim; do ln -sfn "$2/$p" "$1/hapticopt/$p"; done
}
shim "$TMP/shim-old" "$TMP/old"; shim "$TMP/shim-new" "$ROOT"
run() {  # run SHIM WORKDIR -> seconds of the three commands: total evaluate export optimise
    rm -rf "$2"; mkdir -p "$2"; cd "$2"
    local H=(env PYTHONPATH="$1" "$PY" -c 'import sys; from hapticopt.optim.cli import main; sys.argv=["hapticopt"]+sys.argv[1:]; main()')
    local t0 t1 t2 t3; t0=$(date +%s.%N)
    "${H[@]}" evaluate --preset prrr-paper >/dev/null 2>&1 || true   # exit 3 is a verdict, not a failure here
    t1=$(date +%s.%N)
    "${H[@]}" export --preset prrr-paper --render >/dev/null 2>&1
    t2=$(date +%s.%N)
    "${H[@]}" optimise prrr-workspace --quiet >/dev/null 2>&1 || true
    t3=$(date +%s.%N)
    python3 -c "print(f'{$t3 - $t0:.1f} {$t1 - $t0:.2f} {$t2 - $t1:.2f} {$t3 - $t2:.2f}')"
}
for i in $(seq "$PAIRS"); do
    read -r o oe ox oo < <(run "$TMP/shim-old" "$TMP/run-old"); read -r n ne nx no < <(run "$TMP/shim-new" "$TMP/run-new")
    python3 -c "print(f'pair $i: old {$o:.1f} s, new {$n:.1f} s, ratio {$n / $o:.2f}'
                      f' (evaluate {$ne / $oe:.2f}, export {$nx / $ox:.2f}, optimise {$no / $oo:.2f}); load $(cut -d' ' -f1-3 /proc/loadavg)')"
done
