#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# The newcomer's check: what a new machine does with this repository.  Clones the committed
# HEAD into a temporary folder and runs the README's two commands there (`make demo`, then
# `make test`) with every cache of the project rebuilt: a new venv (from requirements.lock, with
# an empty pip cache), new FreeCAD 1.0 and 1.1 chroots in the temporary folder, and a throw-away
# HOME whose FreeCAD Mod folders link to the clone (the user's own are not touched).  Debian
# packages on the host are shared (apt cannot be undone); setup installs what is missing.
#
# Usage: tools/fresh_check.sh [--keep]     (make fresh-check)
#   --keep   keep the temporary folder even when everything passed (it is kept on failure)
# Run it after any change to set-up or dependencies.  Needs root and the network (~25 min).
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
keep=0
for arg in "$@"; do
  case "$arg" in
    --keep) keep=1 ;;
    *) echo "fresh_check.sh: unknown option $arg (only --keep)" >&2; exit 2 ;;
  esac
done
# Not under /tmp: the chroots bind the host's /tmp into themselves.
work="$(mktemp -d -p /var/tmp bsplinecam-fresh.XXXXXX)"
say() { printf '[fresh-check] %s\n' "$*" >&2; }
if [ -n "$(git -C "$root" status --porcelain --untracked-files=no)" ]; then
  say "note: uncommitted changes in $root are not part of the check (it clones HEAD)"
fi
git clone -q "$root" "$work/repo" || { say "error: git clone failed"; exit 1; }
mkdir -p "$work/home"
export HOME="$work/home" XDG_DATA_HOME="$work/home/.local/share" XDG_CONFIG_HOME="$work/home/.config"
export BSPLINECAM_CHROOTS="$work/chroots" PIP_NO_CACHE_DIR=1
unset BSPLINECAM_TRIXIE BSPLINECAM_SID
say "clone of $(git -C "$work/repo" rev-parse --short HEAD) in $work/repo; chroots in $BSPLINECAM_CHROOTS"
start=$SECONDS
rc=0
( cd "$work/repo" && make demo ) >"$work/demo.log" 2>&1 || rc=$?
say "make demo: exit $rc ($((SECONDS - start)) s), log $work/demo.log"
tail -n 8 "$work/demo.log" | sed 's/^/   | /' >&2
if [ "$rc" = 0 ]; then
  t=$SECONDS
  ( cd "$work/repo" && make test ) >"$work/test.log" 2>&1 || rc=$?
  say "make test: exit $rc ($((SECONDS - t)) s), log $work/test.log"
  grep -E '^== |passed, [0-9]+ failed$|^failed suites' "$work/test.log" | sed 's/^/   | /' >&2
fi
if [ "$rc" = 0 ] && [ "$keep" = 0 ]; then
  rm -rf --one-file-system "$work"
  say "passed in $((SECONDS - start)) s; temporary folder removed"
else
  say "$([ "$rc" = 0 ] && echo passed || echo FAILED) in $((SECONDS - start)) s; everything is kept in $work"
fi
exit "$rc"
