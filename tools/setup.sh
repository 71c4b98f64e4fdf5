#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# Install what is missing, idempotently: Debian packages (FreeCAD 0.20, LinuxCNC's rs274, Xvfb),
# the project venv (cadquery) from requirements.lock, the addon link into FreeCAD's user Mod
# folder, and with --test the FreeCAD 1.0 and 1.1 chroots.  Safe to run again: each step checks
# before it installs; a step that fails (no network, say) says what is missing and exits non-zero.
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

debian_packages=(freecad xvfb xauth linuxcnc-uspace python3-pip python3-matplotlib python3-scipy python3-numba)
if [ "$want_test" = 1 ]; then
  debian_packages+=(python3-pytest python3-pytest-xdist python3-hypothesis debootstrap)
fi
missing=()
for pkg in "${debian_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ "${#missing[@]}" -gt 0 ]; then
  say "installing Debian packages: ${missing[*]}"
  if ! apt-get update -qq || ! DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
      --no-install-recommends "${missing[@]}" >/dev/null; then
    say "error: apt-get could not install ${missing[*]} (no network, or another apt running?); run tools/setup.sh again"
    exit 1
  fi
fi

# OpenCAMLib for FreeCAD 0.20's own 3D Surface op (benchmark peer): Debian's Python 3.11 takes
# the PyPI wheel; FreeCAD 0.20 imports it as "ocl", so a one-line alias module goes beside it.
site=$(/usr/bin/python3 -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])' | sed 's#/usr/lib/#/usr/local/lib/#')
if ! /usr/bin/python3 -c 'import ocl' 2>/dev/null; then
  say "installing opencamlib for FreeCAD's Python"
  /usr/bin/python3 -m pip install -q --no-deps --break-system-packages --root-user-action=ignore \
    -r "$root/requirements-freecad-python.txt" \
    || { say "error: could not install opencamlib from PyPI (no network?); run tools/setup.sh again"; exit 1; }
  /usr/bin/python3 -c 'import ocl' 2>/dev/null || {
    mkdir -p "$site"
    printf '%s\n' '"""FreeCAD 0.20 imports OpenCAMLib as ocl; the PyPI wheel names it opencamlib.ocl."""' \
      'from opencamlib.ocl import *  # noqa: F401,F403' > "$site/ocl.py"
  }
fi

venv="$root/.venv"
lock="$root/requirements.lock"
# The venv is installed from the lock (every package pinned, transitive ones included, no
# resolver at work) and rebuilt whenever the lock changes; tools/lock.sh refreshes the lock.
lock_sum=$(sha256sum "$lock" | cut -d' ' -f1)
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$venv/.bsplinecam-lock" 2>/dev/null)" != "$lock_sum" ] \
    || ! "$venv/bin/python" -c 'import OCP, cadquery, scipy, geomdl, pytest, hypothesis, matplotlib' 2>/dev/null; then
  say "creating the project venv from requirements.lock (cadquery, references, test tools) in $venv"
  rm -rf "$venv"
  python3 -m venv "$venv"
  if ! "$venv/bin/pip" install -q --no-deps -r "$lock" || ! "$venv/bin/pip" check >/dev/null; then
    rm -rf "$venv"  # nothing half-installed: the next run starts again
    say "error: could not install requirements.lock from PyPI (no network?); run tools/setup.sh again when it is reachable"
    exit 1
  fi
  echo "$lock_sum" >"$venv/.bsplinecam-lock"
fi

# Install the addon as the Addon Manager would: the repo linked into the Mod folder that FreeCAD
# reports (0.20 and 1.0: ~/.local/share/FreeCAD/Mod; 1.1: .../v1-1/Mod).  A folder already there
# is moved aside, never deleted.
linked=$(/usr/bin/python3 "$root/tools/install_addon.py" --freecadcmd freecadcmd) || exit 1
say "$linked"

if [ "$want_test" = 1 ]; then
  # FreeCAD 1.0 (Debian trixie) and 1.1 (Debian sid) in cached chroots, the addon installed in
  # each as above (the repo is mounted there at the same path)
  for v in 1.0 1.1; do
    "$root/tools/freecad-chroot.sh" "$v" ensure
    linked=$("$root/tools/freecad-chroot.sh" "$v" run python3 "$root/tools/install_addon.py" --freecadcmd freecadcmd) || exit 1
    say "FreeCAD $v: $linked"
  done
fi
say "ready"
