#!/usr/bin/env bash
# Installs what tools/mitsuba/ needs: Mitsuba 3 and numpy in a virtual
# environment at tools/mitsuba/.venv, and (for the default llvm_ad_rgb
# variant) a shared libLLVM >= 16 from Debian's packages. Safe to rerun.
#
#   bash tools/mitsuba/setup.sh
#   tools/mitsuba/.venv/bin/python tools/mitsuba/export.py SCENE.xml -o OUT.pds --spp 16
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="$here/.venv"

# drjit 1.5 aborts with libLLVM-15; Debian 12 has 19 in its main archive.
if ! /sbin/ldconfig -p | grep -qE 'libLLVM(-|\.so\.)(1[6-9]|[2-9][0-9])'; then
    sudo_=""
    [ "$(id -u)" -ne 0 ] && sudo_="sudo"
    $sudo_ apt-get update -q
    DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -q libllvm19
fi

[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
    "mitsuba==3.9.1" "drjit==1.5.0" numpy
"$venv/bin/python" -c "import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); \
print('Mitsuba', mi.__version__, 'ready:', '$venv/bin/python')"
