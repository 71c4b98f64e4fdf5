#!/usr/bin/env bash
# Run the GUI tests in a real FreeCAD GUI under Xvfb; exit non-zero on failure.
#
# Usage: tools/run_gui_test.sh [MODULE...]      default: TestBSplineCAMGuiCam TestBSplineCAMGuiPanels TestBSplineCAMGui TestBSplineCAMGuiPart
# Environment:
#   FREECAD             GUI binary (default: freecad)
#   FREECADCMD          its command-line twin, asked where the Mod folder is (default: freecadcmd)
#   BSPLINECAM_TIMEOUT  seconds before FreeCAD is killed (default: 900)
#   BSPLINECAM_DOCS     where screenshots go (default: build/screenshots/; `make screenshots`
#                       writes them to docs/ on purpose)
#
# FreeCAD runs with a throw-away HOME whose Mod folder links to this repository, so the test
# neither depends on nor changes the user's FreeCAD settings.  Writes view3d.png,
# workbench.png, net_editor.png, verify3d.png (the simulated part coloured by deviation),
# job.png (the bench with a machining job), part_verify.png (a part job verified) and more.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FREECAD="${FREECAD:-freecad}"
TIMEOUT="${BSPLINECAM_TIMEOUT:-900}"
WORK="$(mktemp -d -t bsplinecam-gui.XXXXXX)"
trap 'rm -rf "$WORK"' EXIT

mkdir -p "$WORK/home"
# the compiled kernels stay in the user's cache folder (the throw-away HOME would compile them
# at every run)
export BSPLINECAM_CACHE="${BSPLINECAM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/bsplinecam/numba}"
export HOME="$WORK/home"
export XDG_CONFIG_HOME="$HOME/.config" XDG_DATA_HOME="$HOME/.local/share"
# the Mod folder this FreeCAD reads (1.1's is versioned), as FreeCAD itself reports it
python3 "$ROOT/tools/install_addon.py" --freecadcmd "${FREECADCMD:-freecadcmd}" >/dev/null
export BSPLINECAM_GUI_OUT="$WORK/result.json"
export BSPLINECAM_GUI_TESTS="${*:-TestBSplineCAMGuiCam TestBSplineCAMGuiPanels TestBSplineCAMGui TestBSplineCAMGuiPart}"
export BSPLINECAM_DOCS="${BSPLINECAM_DOCS:-$ROOT/build/screenshots}"
[[ $EUID -eq 0 ]] && export QTWEBENGINE_DISABLE_SANDBOX=1

cd "$ROOT"
rc=0
timeout --kill-after=15 "$TIMEOUT" \
    xvfb-run -a -s "-screen 0 1920x1200x24" "$FREECAD" "$ROOT/tests/gui_run_tests.py" \
    >"$WORK/freecad.log" 2>&1 || rc=$?

[[ -f "$WORK/result.log" ]] && cat "$WORK/result.log"
cp "$WORK/freecad.log" "${TMPDIR:-/tmp}/bsplinecam-gui-freecad.log" 2>/dev/null || true
if [[ ! -f "$BSPLINECAM_GUI_OUT" ]]; then
    echo "run_gui_test: FreeCAD wrote no result (exit $rc; 124 = timeout). Its output:" >&2
    tail -n 60 "$WORK/freecad.log" >&2
    exit 1
fi
if ! python3 -c 'import json, sys; sys.exit(0 if json.load(open(sys.argv[1]))["ok"] else 1)' \
    "$BSPLINECAM_GUI_OUT"; then
    echo "run_gui_test: FAILED (FreeCAD exit $rc); result: $BSPLINECAM_GUI_OUT" >&2
    python3 -m json.tool "$BSPLINECAM_GUI_OUT" >&2 || true
    exit 1
fi
[[ $rc -eq 0 ]] || { echo "run_gui_test: tests passed but FreeCAD exited $rc" >&2; exit "$rc"; }
echo "run_gui_test: OK; screenshots in $BSPLINECAM_DOCS"
