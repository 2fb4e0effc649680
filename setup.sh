#!/usr/bin/env bash
# Sets everything up in this checkout and runs the demo:
#   - Debian's GL/X libraries the bpy module loads (Mesa's software GL lets EEVEE render headless),
#     installed only when missing;
#   - a virtual environment with the bpy module of the newest supported Blender this machine can run (the newest
#     one whose Python is found), numpy and the test tools; it says which it installed;
#   - embreex, the optional Embree ray engine's binding, where it has a wheel (x86-64), and the wheels the
#     extension's zips bundle, into wheels/ (wheels/fetch.py: the manifest's list, each file's hash checked);
#   - this checkout as a package of that environment (pyproject.toml, editable: the environment runs the checkout as
#     it is), which gives the `prt` command and `python -m prt_addon` in any folder;
#   - the sample scenes, built in that Blender's file format (sample_scenes/make_scenes.py);
#   - the browser viewer's three.js and, for the tests, Khronos' glTF validator (npm install in viewer/), and
#     Debian's chromium, which its tests drive;
#   - `prt demo`, which writes a PNG and a JSON report into demo_output/.
# Options:
#   --blender X.Y   that Blender instead (one of the supported versions below)
#   --venv DIR      the virtual environment's folder (default .venv)
#   --no-demo       stop after the install and the sample scenes
set -euo pipefail
cd "$(dirname "$0")"

# Supported Blenders, newest first: version, the Python its bpy module needs, the bpy release tested.
# 4.5 LTS is the oldest the manifest admits (blender_version_min); CI runs the suite on each of them.
SUPPORTED="5.3 3.13 5.3.0
5.2 3.13 5.2.3
5.0 3.11 5.0.1
4.5 3.11 4.5.15"

blender="" venv=".venv" demo=1
while [ $# -gt 0 ]; do
  case "$1" in
    --blender) blender="$2"; shift 2 ;;
    --venv) venv="$2"; shift 2 ;;
    --no-demo) demo=0; shift ;;
    *) echo "setup: unknown option $1 (expected --blender X.Y, --venv DIR, --no-demo)" >&2; exit 1 ;;
  esac
done

find_python() {  # the interpreter for Python $1 (X.Y): on PATH, else pyenv's, else nothing
  local candidate
  for candidate in "python$1" "${PYENV_ROOT:-$HOME/.pyenv}"/versions/"$1".*/bin/"python$1" "/usr/bin/python$1"; do
    if command -v "$candidate" >/dev/null 2>&1 && "$candidate" -c "import sys" >/dev/null 2>&1; then
      command -v "$candidate"
      return 0
    fi
  done
  return 1
}

python="" python_needed="" bpy_version=""
while read -r version python_version release; do
  if [ -n "$blender" ] && [ "$blender" != "$version" ]; then
    continue
  fi
  if found=$(find_python "$python_version"); then
    python="$found" python_needed="$python_version" bpy_version="$release" blender="$version"
    break
  fi
  if [ -n "$blender" ]; then
    echo "setup: Blender $blender needs Python $python_version, which this machine does not have" >&2
    exit 1
  fi
done <<< "$SUPPORTED"
if [ -z "$python" ]; then
  echo "setup: ${blender:+Blender $blender is not supported; }supported Blenders and their Pythons:" >&2
  echo "$SUPPORTED" | awk '{print "  Blender " $1 " (bpy " $3 ") on Python " $2}' >&2
  exit 1
fi

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

python_of() {  # X.Y of the interpreter $1
  "$1" -c "import sys; print('%d.%d' % sys.version_info[:2])"
}
if [ -x "$venv/bin/python" ] && [ "$(python_of "$venv/bin/python")" != "$python_needed" ]; then
  echo "setup: $venv has Python $(python_of "$venv/bin/python"), Blender $blender needs $python_needed; making it anew"
  rm -rf "$venv"
fi
if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q "bpy==$bpy_version" -r requirements-dev.txt
# The version of the wheels blender_manifest.toml bundles (tests/test_install.py checks that they agree).
"$venv/bin/python" -m pip install -q --only-binary embreex "embreex==4.4.0.post1; platform_machine == 'x86_64'"
"$venv/bin/python" wheels/fetch.py
"$venv/bin/python" -m pip install -q -e .
echo "setup: installed Blender $("$venv/bin/python" -c 'import bpy; print(bpy.app.version_string)') (bpy $bpy_version) on Python $("$venv/bin/python" -c 'import platform; print(platform.python_version())') in $venv"

"$venv/bin/python" sample_scenes/make_scenes.py

# The viewer's tests drive Debian's chromium through Playwright (never a browser download of Playwright's own).
missing=""
for tool in chromium npm; do
  command -v "$tool" >/dev/null 2>&1 || missing="$missing $tool"
done
if [ -n "$missing" ]; then
  echo "setup: installing Debian packages for the browser viewer:$missing"
  sudo_cmd=""; [ "$(id -u)" = 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -q $missing
fi
(cd viewer && npm install --no-audit --no-fund --silent)

if [ "$demo" = 1 ]; then
  "$venv/bin/prt" demo --output demo_output
fi
