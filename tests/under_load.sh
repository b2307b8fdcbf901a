#!/usr/bin/env bash
# `make test-under-load`: the whole suite on a busy machine, two ways.
#   hogs:   this checkout's suite with four CPU hogs (twice the cores of the reference
#           machine) running beside it;
#   clones: two fresh clones of HEAD, each running `make test` (its own virtualenv) at the
#           same time, as two CI jobs on one runner would.
# Usage: bash tests/under_load.sh [hogs|clones|all]   (default all; HOGS=N changes the hogs)
# Exit status: non-zero when any suite fails.
set -uo pipefail
cd "$(dirname "$0")/.."
what="${1:-all}"
PY="$PWD/.venv/bin/python"
HOGS="${HOGS:-4}"
work="$(mktemp -d)"
hogs=()
cleanup() {
  for p in "${hogs[@]}"; do kill "$p" 2>/dev/null; done
  rm -rf "$work"
}
trap cleanup EXIT
status=0

if [ "$what" = hogs ] || [ "$what" = all ]; then
  echo "== the suite with $HOGS CPU hogs"
  for _ in $(seq "$HOGS"); do "$PY" -c "while True: pass" & hogs+=($!); done
  start=$(date +%s)
  "$PY" -m pytest -q -n auto --dist worksteal -p no:cacheprovider || status=1
  echo "(with $HOGS hogs: $(( $(date +%s) - start )) s)"
  for p in "${hogs[@]}"; do kill "$p" 2>/dev/null; done
  hogs=()
fi

if [ "$what" = clones ] || [ "$what" = all ]; then
  echo "== two fresh clones running make test side by side"
  for i in 1 2; do git clone -q . "$work/clone$i"; done
  start=$(date +%s)
  pids=()
  for i in 1 2; do
    (cd "$work/clone$i" && make test > "$work/log$i" 2>&1) &
    pids+=($!)
  done
  for i in 1 2; do
    if wait "${pids[$((i - 1))]}"; then res=passed; else res=FAILED; status=1; fi
    echo "clone $i: $res: $(tail -n 1 "$work/log$i")"
    [ "$res" = FAILED ] && tail -n 60 "$work/log$i"
  done
  echo "(side by side: $(( $(date +%s) - start )) s)"
fi
exit $status
