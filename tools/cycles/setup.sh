#!/usr/bin/env bash
# Installs what tools/cycles/ needs: Blender as a Python module (the `bpy`
# wheel, Blender 5.x, which runs only on Python 3.13) and numpy, in a virtual
# environment at tools/cycles/.venv. Safe to rerun: quiet when already set up.
#
#   bash tools/cycles/setup.sh
#   tools/cycles/.venv/bin/python tools/cycles/export.py builtin:caustic -o OUT.pds --spp 16
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="$here/.venv"
py313="${PATHDENSITY_PYTHON313:-$HOME/.pyenv/versions/3.13.0/bin/python3}"
# The version the measurements in docs/renderers.md were made with.
bpy_version=5.3.0
check="import bpy, numpy; assert bpy.app.version_string.split()[0] == '$bpy_version', bpy.app.version_string"

if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c "$check" 2>/dev/null; then
    exit 0
fi
if [ ! -x "$py313" ]; then
    py313="$(command -v python3.13 || true)"
fi
if [ -z "$py313" ] || ! "$py313" -c 'import sys; assert sys.version_info[:2] == (3, 13)' 2>/dev/null; then
    echo "tools/cycles/setup.sh: the bpy wheel needs Python 3.13 (~/.pyenv/versions/3.13.0 or python3.13)" >&2
    exit 1
fi
start=$(date +%s)
[ -x "$venv/bin/python" ] || "$py313" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check "bpy==$bpy_version" numpy
"$venv/bin/python" -c "$check; print('Blender', bpy.app.version_string, 'ready:', '$venv/bin/python')" 2>/dev/null \
    | grep -v '^$' || { echo "tools/cycles/setup.sh: bpy does not import" >&2; exit 1; }
echo "tools/cycles/setup.sh: installed in $(( $(date +%s) - start )) s"
