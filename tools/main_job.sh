#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# The main job on the case study, from control net to verified G-code, in out/case-study/:
#   1. surface: exact transfer to FreeCAD and cadquery (STEP, BREP, FCStd, .dat) + cross-check
#   2. job:     block to part in one FreeCAD Job: Z-level roughing with a flat end mill (T1,
#               stock to leave), rest passes and the ball-end finish on the exact surface (T2);
#               one program with tool changes through FreeCAD's linuxcnc, grbl, fanuc and
#               mach3_mach4 posts, each checked by rs274
#   3. verify:  (inside job) the linuxcnc program's text simulated from the stock block with
#               both tools and measured against the design: gouge, scallop, rapids, and the
#               roughing's radial engagement within 1.1 x its stepover
# Exits non-zero if any stage fails its check.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
net="${BSPLINECAM_NET:-$root/examples/case-study.json}"
out="${1:-$root/out/case-study}"
tool="${BSPLINECAM_TOOL:-6}"
scallop="${BSPLINECAM_SCALLOP:-0.01}"
rough="${BSPLINECAM_ROUGH:-flat:10}"
mkdir -p "$out"
say() { printf '\n[main job] %s\n' "$*" >&2; }

say "1/3 surface: exports and cross-check against OCCT -> $out"
"$root/bin/bsplinecam" surface "$net" --out "$out"

say "2/3 job: block + 2 mm -> $rough roughing (step-down 2, stepover 40 %, 0.3 mm to leave) -> ball ${tool} mm rest + raster finish (scallop ${scallop} mm); 4 posts, rs274"
say "3/3 verify: the program simulated from the block with both tools, measured against the design"
status=0
"$root/bin/bsplinecam" job "$net" --stock-margin 2 --rough "$rough" --stepdown 2 --stepover 40 \
    --allowance 0.3 --finish "ball:$tool" --scallop "$scallop" \
    --post linuxcnc,grbl,fanuc,mach3_mach4 --out "$out" >/dev/null || status=$?
# 1: a check failed (the results are written, the summary shows which); else: no results
[[ -f "$out/verify.json" && ( $status -eq 0 || $status -eq 1 ) ]] || exit "$((status ? status : 1))"

/usr/bin/python3 - "$out" "$status" <<'PY'
import json, sys
out, status = sys.argv[1], int(sys.argv[2])
cross = json.load(open(f"{out}/crosscheck.json"))
job = json.load(open(f"{out}/job.json"))
ver = json.load(open(f"{out}/verify.json"))
rough, t1, t2 = job["roughing"], ver["tools"]["1"], ver["tools"]["2"]
print("\n[main job] summary")
print(f"  exact transfer: max deviation {max(v for v in cross['max_deviation_mm'].values() if v is not None):.2e} mm "
      f"(paper's loft route {cross['paper_route']['max_deviation_mm']:.3f} mm)")
print(f"  stock block {' x '.join(f'{b - a:.1f}' for a, b in zip(job['stock_mm'][::2], job['stock_mm'][1::2]))} mm")
print(f"  roughing T1 ({t1['tool']['shape']} {t1['tool']['diameter_mm']:g} mm): {len(rough['levels'])} levels, "
      f"{rough['program_moves']} moves, computed in {rough['seconds']:.1f} s; removed {t1['removed_volume_mm3'] / 1000:.1f} cm3, "
      f"radial engagement max {t1['radial_engagement_max_mm']:.2f} mm, axial max {t1['axial_engagement_max_mm']:.2f} mm")
rest = job.get("rest", {})
print(f"  finishing T2 (ball {t2['tool']['diameter_mm']:g} mm): {rest.get('passes', 0)} rest passes "
      f"({rest.get('seconds', 0):.1f} s) + {job['passes']} raster passes ({job['seconds']:.1f} s), "
      f"deepest cut {t2['axial_engagement_max_mm']:.2f} mm")
print("  rs274: " + ", ".join(f"{post} {'ok' if r['ok'] else r['message']}"
                             for post, r in job.get("rs274_by_post", {}).items()))
print(f"  machined from the block: gouge {ver['gouge_max_mm'] * 1000:.2f} um, scallop max {ver['scallop_max_mm']:.4f} mm "
      f"(p99 {ver['scallop_p99_mm']:.4f}), coverage {100 * ver['coverage']:.2f} %, "
      f"rapid collisions {len(ver['rapid_collisions'])}, {ver['machining_time_s'] / 60:.1f} min "
      f"({ver['machining_time_with_acceleration_s'] / 60:.1f} min with acceleration)")
for name, check in ver["checks"].items():
    print(f"    {'ok  ' if check['ok'] else 'FAIL'} {name}: {check['value']} (limit {check['limit']})")
# the roughing's engagement is a target for `job` in general (see the README's known
# limits); the case study meets it, so here it is a check like the others
for name, target in ver.get("targets", {}).items():
    print(f"    {'ok  ' if target['ok'] else 'FAIL'} {name}: {target['value']} (limit {target['limit']})")
ok = status == 0 and cross["exact_route_ok"] and ver["ok"] and all(
    r["ok"] for r in job.get("rs274_by_post", {}).values()) and all(
    t["ok"] for t in ver.get("targets", {}).values())
sys.exit(0 if ok else 1)
PY
