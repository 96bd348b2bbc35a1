#!/usr/bin/env bash
# Builds the Python module `pathdensity` (crates/python, one release build
# through maturin in the workspace's target/) into tools/python/.venv, with
# numpy and pytest for its tests (tests/python_module.rs runs them).
# Safe to rerun: cargo rebuilds only what changed. Quiet unless it fails;
# prints how long the build took.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
venv="$root/tools/python/.venv"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    "maturin>=1.9,<2" numpy pytest >"$log" 2>&1; then
    cat "$log" >&2
    exit 1
fi
start=$(date +%s)
if ! (cd "$root/crates/python" && VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH" \
    maturin develop --release) >"$log" 2>&1; then
    cat "$log" >&2
    echo "tools/python/setup.sh: building the module failed (above)" >&2
    exit 1
fi
echo "pathdensity Python module: built and installed in $(( $(date +%s) - start )) s ($venv)"
