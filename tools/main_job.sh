#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# The main job on the case study, from control net to verified G-code, in out/case-study/:
#   1. surface:  exact transfer to FreeCAD and cadquery (STEP, BREP, FCStd, .dat) + cross-check
#   2. toolpath: FreeCAD Job, ball-end finishing op on the exact surface, linuxcnc post, rs274
#   3. verify:   the program's text simulated on a Z-map and measured against the design
# Exits non-zero if any stage fails its check.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
net="${BSPLINECAM_NET:-$root/examples/case-study.json}"
out="${1:-$root/out/case-study}"
tool="${BSPLINECAM_TOOL:-6}"
scallop="${BSPLINECAM_SCALLOP:-0.01}"
mkdir -p "$out"
say() { printf '\n[main job] %s\n' "$*" >&2; }

say "1/3 surface: exports and cross-check against OCCT -> $out"
"$root/bin/bsplinecam" surface "$net" --out "$out"

say "2/3 toolpath: ${tool} mm ball, scallop ${scallop} mm, raster on the exact surface, linuxcnc post, rs274"
"$root/bin/bsplinecam" toolpath "$net" --tool-diameter "$tool" --scallop "$scallop" --post linuxcnc --out "$out"

say "3/3 verify: simulate the G-code and measure it against the design"
"$root/bin/bsplinecam" verify "$net" "$out/case-study.ngc" --tool-diameter "$tool" --out "$out"

/usr/bin/python3 - "$out" "$scallop" <<'PY'
import json, sys
out, scallop = sys.argv[1], float(sys.argv[2])
cross = json.load(open(f"{out}/crosscheck.json"))
path = json.load(open(f"{out}/toolpath.json"))
ver = json.load(open(f"{out}/verify.json"))
print("\n[main job] summary")
print(f"  exact transfer: max deviation {max(v for v in cross['max_deviation_mm'].values() if v is not None):.2e} mm "
      f"(paper's loft route {cross['paper_route']['max_deviation_mm']:.3f} mm)")
print(f"  toolpath: {path['passes']} passes, {path['moves']} moves, {path['cutting_length_mm']:.0f} mm, "
      f"computed in {path['seconds']:.1f} s; rs274: {'ok' if path['rs274']['ok'] else path['rs274']['message']}")
print(f"  machined: gouge {ver['gouge_max_mm'] * 1000:.2f} um, scallop max {ver['scallop_max_mm']:.4f} mm "
      f"(p99 {ver['scallop_p99_mm']:.4f}), coverage {100 * ver['coverage']:.2f} %, "
      f"rapid collisions {len(ver['rapid_collisions'])}, {ver['machining_time_s'] / 60:.1f} min")
ok = cross["exact_route_ok"] and path["rs274"]["ok"] and not ver["rapid_collisions"]
sys.exit(0 if ok else 1)
PY
