#!/usr/bin/env bash
# `make test-under-load`: the whole suite on a busy machine, two ways.
#   1. with four CPU hogs (twice the cores of the reference machine) beside it;
#   2. two full suites side by side, each in its own fresh clone of HEAD (two CI jobs on one
#      runner).
# Both clones use this checkout's virtualenv (each imports its own copy of the code, being
# run from its own directory). Exit status: non-zero when any suite fails.
set -uo pipefail
cd "$(dirname "$0")/.."
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
echo "== 1. the suite with $HOGS CPU hogs"
for _ in $(seq "$HOGS"); do "$PY" -c "while True: pass" & hogs+=($!); done
start=$(date +%s)
"$PY" -m pytest -q -p no:cacheprovider || status=1
echo "(with $HOGS hogs: $(( $(date +%s) - start )) s)"
for p in "${hogs[@]}"; do kill "$p" 2>/dev/null; done
hogs=()

echo "== 2. two suites side by side from two fresh clones"
for i in 1 2; do
  git clone -q . "$work/clone$i"
  ln -s "$(cd .. && pwd)/shared" "$work/shared" 2>/dev/null || true
done
start=$(date +%s)
pids=()
for i in 1 2; do
  (cd "$work/clone$i" && "$PY" -m pytest -q -p no:cacheprovider > "$work/log$i" 2>&1) &
  pids+=($!)
done
for i in 1 2; do
  if wait "${pids[$((i - 1))]}"; then res=passed; else res=FAILED; status=1; fi
  echo "clone $i: $res: $(tail -n 1 "$work/log$i")"
  [ "$res" = FAILED ] && tail -n 40 "$work/log$i"
done
echo "(side by side: $(( $(date +%s) - start )) s)"
exit $status
