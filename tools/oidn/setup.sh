#!/usr/bin/env bash
# Installs Intel Open Image Denoise for pathdensity, which loads it at run
# time: the PyPI wheel pyoidn (OIDN 2.5 with its CPU device and TBB) into
# tools/oidn/.venv. Debian has no OIDN package. Prints the OIDN_DIR that
# points pathdensity at it; safe to rerun.
#
#   eval "$(bash tools/oidn/setup.sh)"      # exports OIDN_DIR
#   pathdensity filter DUMP -o OUT          # says "denoiser: OIDN 2.5.1 (...)"
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="$here/.venv"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv" >&2
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    "pyoidn==2.5.1.0" numpy >&2
dir="$("$venv/bin/python" -c 'import os, pyoidn; print(os.path.join(os.path.dirname(pyoidn.__file__), "oidn"))')"
[ -e "$dir/lib/libOpenImageDenoise.so" ] || { echo "no libOpenImageDenoise.so under $dir/lib" >&2; exit 1; }
echo "export OIDN_DIR=$dir"
