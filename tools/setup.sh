#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# Install what is missing, idempotently: Debian packages (FreeCAD 0.20, LinuxCNC's rs274, Xvfb),
# the project venv (cadquery), the addon link into FreeCAD's user Mod folder, and with --test the
# FreeCAD 1.0 chroot.  Safe to run again: each step checks before it installs.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
want_test=0
for arg in "$@"; do
  case "$arg" in
    --test) want_test=1 ;;
    *) echo "setup.sh: unknown option $arg" >&2; exit 2 ;;
  esac
done
say() { printf '[setup] %s\n' "$*" >&2; }

debian_packages=(freecad xvfb xauth linuxcnc-uspace python3-pip python3-matplotlib python3-scipy)
if [ "$want_test" = 1 ]; then
  debian_packages+=(python3-pytest python3-hypothesis debootstrap)
fi
missing=()
for pkg in "${debian_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ "${#missing[@]}" -gt 0 ]; then
  say "installing Debian packages: ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# OpenCAMLib for FreeCAD 0.20's own 3D Surface op (benchmark peer): Debian's Python 3.11 takes
# the PyPI wheel; FreeCAD 0.20 imports it as "ocl", so a one-line alias module goes beside it.
site=$(/usr/bin/python3 -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])' | sed 's#/usr/lib/#/usr/local/lib/#')
if ! /usr/bin/python3 -c 'import ocl' 2>/dev/null; then
  say "installing opencamlib for FreeCAD's Python"
  /usr/bin/python3 -m pip install -q --break-system-packages --root-user-action=ignore opencamlib
  /usr/bin/python3 -c 'import ocl' 2>/dev/null || {
    mkdir -p "$site"
    printf '%s\n' '"""FreeCAD 0.20 imports OpenCAMLib as ocl; the PyPI wheel names it opencamlib.ocl."""' \
      'from opencamlib.ocl import *  # noqa: F401,F403' > "$site/ocl.py"
  }
fi

venv="$root/.venv"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import OCP, cadquery, scipy, geomdl, pytest, hypothesis, matplotlib' 2>/dev/null; then
  say "creating the project venv (cadquery, references, test tools) in $venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --upgrade pip
  "$venv/bin/pip" install -q -r "$root/requirements-dev.txt"
fi

# Install the addon as the Addon Manager would: the repo linked into FreeCAD's user Mod folder.
mod="${HOME}/.local/share/FreeCAD/Mod"
mkdir -p "$mod"
if [ "$(readlink -f "$mod/BSplineCAM" 2>/dev/null)" != "$root" ]; then
  rm -rf "$mod/BSplineCAM"
  ln -s "$root" "$mod/BSplineCAM"
  say "linked $mod/BSplineCAM -> $root"
fi

if [ "$want_test" = 1 ]; then
  "$root/tools/freecad10.sh" ensure
  # the same install inside the FreeCAD 1.0 chroot (the repo is mounted there at the same path)
  "$root/tools/freecad10.sh" run sh -c 'mkdir -p "$HOME/.local/share/FreeCAD/Mod" && ln -sfn "$1" "$HOME/.local/share/FreeCAD/Mod/BSplineCAM"' sh "$root"
fi
say "ready"
