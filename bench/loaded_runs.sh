#!/usr/bin/env bash
# The suite under load: RUNS consecutive runs of the README's test command (pip install '.[test]', then
# pytest with CI=true), each in a fresh clone of COMMIT and a fresh virtual environment, beside two busy
# loops (`while :; do :; done` in bash, one per core of a 2-core machine). It stops at the first run that
# fails; each run's pytest output is kept in OUT/runN.txt, and one line a run goes to OUT/summary.txt.
#
#   bench/loaded_runs.sh [--runs N] [--python PYTHON] [--out DIR] [COMMIT]
#
# COMMIT defaults to HEAD, PYTHON to python3, DIR to bench/results/loaded; PYTEST_ARGS (unset: the whole
# suite) narrows the runs, to try this script on a few tests. Exit 0 when every run passed.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
runs=5 python=python3 out="$root/bench/results/loaded"
while [ $# -gt 0 ]; do
    case "$1" in
        --runs) runs=$2; shift 2 ;;
        --python) python=$2; shift 2 ;;
        --out) out=$2; shift 2 ;;
        -*) echo "loaded_runs.sh: unknown option $1" >&2; exit 2 ;;
        *) break ;;
    esac
done
commit="$(git -C "$root" rev-parse --short "${1:-HEAD}")"
mkdir -p "$out"
echo "--- $runs runs of $commit beside two busy loops, from $(date -u '+%Y-%m-%d %H:%M') UTC" >> "$out/summary.txt"

busy() { while :; do :; done; }
for i in $(seq 1 "$runs"); do
    dir="$(mktemp -d)"
    git clone -q "$root" "$dir/hcrctl" && git -C "$dir/hcrctl" checkout -q "$commit"
    [ -d "$root/../shared" ] && cp -r "$root/../shared" "$dir/shared"  # the protocol's test data, beside it
    "$python" -m venv "$dir/venv"
    (cd "$dir/hcrctl" && "$dir/venv/bin/pip" install -q '.[test]') > "$dir/pip.log" 2>&1
    busy & one=$!
    busy & two=$!
    start=$(date +%s)
    set +e
    # shellcheck disable=SC2086  # PYTEST_ARGS is a list of arguments
    (cd "$dir/hcrctl" && PATH="$dir/venv/bin:$PATH" CI=true "$dir/venv/bin/pytest" -p no:cacheprovider ${PYTEST_ARGS:-}) \
        > "$out/run$i.txt" 2>&1
    rc=$?
    set -e
    kill "$one" "$two"
    echo "run $i of $commit: exit $rc after $(( $(date +%s) - start )) s: $(tail -1 "$out/run$i.txt")" | tee -a "$out/summary.txt"
    rm -rf "$dir"
    [ "$rc" = 0 ] || exit 1
done
