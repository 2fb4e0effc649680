#!/usr/bin/env bash
# Sets everything up in this checkout and runs the demo:
#   - Debian's GL/X libraries the bpy module loads (Mesa's software GL lets EEVEE render headless),
#     installed only when missing;
#   - a virtual environment .venv with bpy 5.0.1, numpy and the test tools;
#   - `python -m prt_addon demo`, which writes a PNG and a JSON report into demo_output/.
# Pass --no-demo to stop after the install.
set -euo pipefail
cd "$(dirname "$0")"

libraries="libGL.so.1 libEGL.so.1 libSM.so.6 libICE.so.6 libX11.so.6 libXext.so.6 libXfixes.so.3 libXi.so.6 libXrender.so.1 libxkbcommon.so.0"
packages="libgl1 libegl1 libegl-mesa0 libgl1-mesa-dri libglx-mesa0 libsm6 libice6 libx11-6 libxext6 libxfixes3 libxi6 libxrender1 libxkbcommon0"
missing=""
for library in $libraries; do
  ldconfig -p | grep -q "$library" || missing="$missing $library"
done
if [ -n "$missing" ]; then
  echo "setup: installing Debian packages for:$missing"
  sudo_cmd=""; [ "$(id -u)" = 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -q $packages
fi

python=${PYTHON:-python3.11}
if [ ! -x .venv/bin/python ]; then
  "$python" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -r requirements-dev.txt

if [ "${1:-}" != "--no-demo" ]; then
  .venv/bin/python -m prt_addon demo --output demo_output
fi
