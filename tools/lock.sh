#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# Refresh requirements.lock: resolve requirements-dev.txt (the packages the project asks for,
# loosely) in a new, empty venv and pin every package it installed, transitive ones included.
# tools/setup.sh installs the venv from the lock alone (pip --no-deps), so a package that moves
# upstream changes nothing until this is run.  Then run the tests: `make lock` does both.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
tmp="$(mktemp -d -t bsplinecam-lock.XXXXXX)"
trap 'rm -rf "$tmp"' EXIT
python3 -m venv "$tmp/venv"
"$tmp/venv/bin/pip" install -q --upgrade pip
if ! "$tmp/venv/bin/pip" install -q -r "$root/requirements-dev.txt"; then
  echo "lock.sh: could not resolve requirements-dev.txt from PyPI (no network?); requirements.lock is unchanged" >&2
  exit 1
fi
{
  echo "# requirements.lock: every PyPI package of the project venv, pinned (transitive ones included)."
  echo "# Made by tools/lock.sh from requirements-dev.txt on $(date -u +%Y-%m-%d) with $("$tmp/venv/bin/python" -V)."
  echo "# Do not edit by hand: change requirements-dev.txt and run 'make lock'."
  "$tmp/venv/bin/pip" freeze --all --exclude pip --exclude setuptools --exclude wheel | LC_ALL=C sort -f
} >"$tmp/requirements.lock"
mv "$tmp/requirements.lock" "$root/requirements.lock"
echo "lock.sh: wrote $root/requirements.lock ($(grep -vc '^#' "$root/requirements.lock") packages)" >&2
