#!/usr/bin/env bash
# FreeCAD 1.0 in its cached Debian chroot: tools/freecad-chroot.sh 1.0 with the same arguments
# (ensure, run, freecadcmd, script, path, versions).
exec "$(dirname "$(readlink -f "${BASH_SOURCE[0]}")")/freecad-chroot.sh" 1.0 "$@"
