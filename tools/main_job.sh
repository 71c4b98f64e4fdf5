#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# The main job on the case study: control net -> exact surface (exports + cross-check).
# Output in out/case-study/ (or $1).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
net="$root/examples/case-study.json"
out="${1:-$root/out/case-study}"
mkdir -p "$out"
echo "[main job] surface: exports and cross-check against OCCT -> $out"
"$root/bin/bsplinecam" surface "$net" --out "$out"
