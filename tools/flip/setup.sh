#!/usr/bin/env bash
# Installs NVIDIA's reference FLIP (the PyPI wheel flip-evaluator) and numpy
# into tools/flip/.venv, for tests/flip.rs, which holds our FLIP to it.
# Safe to rerun.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="$here/.venv"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    "flip-evaluator==$(cat "$here/VERSION")" numpy
