#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# Every test suite, in order; exits non-zero if any test failed.  Assumes tools/setup.sh --test.
#   lint         ruff on the whole tree
#   core-venv    pytest in the project venv (numpy 2.x, cadquery's OCCT, SciPy/geomdl references),
#                the numba engine (the venv's numba)
#   core-debian  pytest in Debian's python3 (numpy 1.24, the Python FreeCAD 0.20 runs), the numpy
#                engine (BSPLINECAM_KERNELS=numpy); its kernel tests compare both engines with
#                Debian's numba, and the FreeCAD suites run the numba engine in all three
#   freecad-0.20 unittest modules inside freecadcmd 0.20
#   freecad-1.0  the same modules inside freecadcmd 1.0 (Debian trixie chroot)
#   freecad-1.1  the same modules inside freecadcmd 1.1 (Debian sid chroot)
#   gui          the real FreeCAD 0.20 GUI under Xvfb (screenshots in docs/)
#   gui-1.0      the real FreeCAD 1.0 GUI under Xvfb in the chroot (build/screenshots-1.0/)
#   gui-1.1      the real FreeCAD 1.1 GUI under Xvfb in the chroot (build/screenshots-1.1/)
#   migration    TestBSplineCAMMigration in 0.20, then 1.0, then 1.1 (each opens the older ones'
#                documents), run apart so that the FreeCAD suites above need no order
# Each log starts with the Debian versions of the packages that suite ran on (FreeCAD, OCCT,
# numpy, Qt bindings, rs274), so a change upstream shows in the log of the run it reached, and
# ends with its ten slowest tests (pytest --durations=10; tools/run_freecad_tests.sh for unittest).
# The last line reads "N passed, N failed" over all tests run.
#
# Keeping CI within its time (issue 42):
# - both core suites run on the machine's two cores (pytest-xdist -n 2, --dist loadfile: a test
#   file's cases share one worker, so a module-scoped fixture such as the corpus's runs is
#   computed once);
# - each slow end-to-end case runs once.  core-debian exists for what numpy 1.24 can change:
#   core numerics, readers, the evaluator.  It skips the cases marked venv_only (-m "not
#   venv_only"): whole toolpath / roughing / verify / part runs, in-process or through
#   bin/bsplinecam (which runs in freecadcmd, i.e. Debian's python3 and numpy, in either suite),
#   that core-venv runs and whose numerics faster unmarked cases cover in both numpys.
#   tests/conftest.py marks whole modules (VENV_ONLY_MODULES), decorators mark single cases;
# - the FreeCAD suites and the GUIs run two at a time in two lanes (two cores, and memory for
#   two FreeCADs many times over); the migration chain, the one order they need, runs first in
#   its lane; the three GUIs share a lane so that no two Xvfb start together; no two freecadcmd
#   of one version overlap.
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
logs="$root/build/test-logs"
mkdir -p "$logs"
rm -f "$logs"/*.rc "$logs"/*.secs  # a suite's status files are written when it ends
export PYTHONDONTWRITEBYTECODE=1
mapfile -t FREECAD_MODULES < <(grep -v '^#' tests/freecad_modules.txt | grep -v '^\s*$')

total_pass=0
total_fail=0
failed_suites=()

# count_pytest LOG -> "passed failed"
count_pytest() {
  local line p f e
  line=$(grep -E '^[=]* ?[0-9]+ (passed|failed)|^[0-9]+ (passed|failed|error)' "$1" | tail -n 1)
  p=$(grep -oE '[0-9]+ passed' <<<"$line" | grep -oE '[0-9]+' || true)
  f=$(grep -oE '[0-9]+ failed' <<<"$line" | grep -oE '[0-9]+' || true)
  e=$(grep -oE '[0-9]+ error' <<<"$line" | grep -oE '[0-9]+' || true)
  echo "${p:-0} $(( ${f:-0} + ${e:-0} ))"
}

# count_unittest LOG -> "passed failed"
count_unittest() {
  local ran f e s
  ran=$(grep -oE '^Ran [0-9]+ test' "$1" | grep -oE '[0-9]+' | awk '{s+=$1} END {print s+0}')
  # "expected failures=N" (a known gap, marked in the test) is no failure
  f=$(grep -oE '(\(|, )failures=[0-9]+' "$1" | grep -oE '[0-9]+' | awk '{s+=$1} END {print s+0}')
  e=$(grep -oE 'errors=[0-9]+' "$1" | grep -oE '[0-9]+' | awk '{s+=$1} END {print s+0}')
  s=$(grep -oE 'skipped=[0-9]+' "$1" | grep -oE '[0-9]+' | awk '{s+=$1} END {print s+0}')
  echo "$(( ran - f - e - s )) $(( f + e ))"
}

# versions WHERE(host|1.0|1.1) -> the Debian versions of the packages a suite runs on
host_reported=(freecad-python3 'libocct-modeling-algorithms-*' python3 python3-numpy 'python3-pyside*.qtcore' linuxcnc-uspace)
versions() {
  if [ "$1" = all ]; then versions host; versions 1.0; versions 1.1; return; fi
  echo "# Debian packages ($1):"
  if [ "$1" = host ]; then
    dpkg-query -W -f='${db:Status-Abbrev} ${Package} ${Version}\n' "${host_reported[@]}" 2>/dev/null | sed -n 's/^ii */#   /p'
  else
    tools/freecad-chroot.sh "$1" versions 2>/dev/null | sed 's/^/#   /'
  fi
}

# run_suite NAME WHERE(host|1.0|1.1|all) CMD...: the log, and its exit status and seconds in
# NAME.rc and NAME.secs beside it (for suites run in the background)
run_suite() {
  local name="$1" where="$2"
  shift 2
  local log="$logs/$name.log" start rc
  start=$(date +%s)
  rm -f "$logs/$name.rc" "$logs/$name.secs"
  versions "$where" >"$log"
  "$@" >>"$log" 2>&1
  rc=$?
  echo "$(( $(date +%s) - start ))" >"$logs/$name.secs"
  echo "$rc" >"$logs/$name.rc"
}

# report NAME KIND(pytest|unittest|plain): the suite's line, its counts added to the totals
report() {
  local name="$1" kind="$2" log="$logs/$1.log" rc p f
  printf '== %-13s ' "$name"
  rc=$(cat "$logs/$name.rc" 2>/dev/null || echo 255)
  case "$kind" in
    pytest) read -r p f < <(count_pytest "$log") ;;
    unittest) read -r p f < <(count_unittest "$log") ;;
    *) if [ "$rc" = 0 ]; then p=1; f=0; else p=0; f=1; fi ;;
  esac
  if [ "$rc" != 0 ] && [ "$f" = 0 ]; then f=1; fi  # a crash that ran no test still fails
  total_pass=$((total_pass + p))
  total_fail=$((total_fail + f))
  printf '%4d passed, %d failed  (exit %d, %ds)  log: %s\n' "$p" "$f" "$rc" "$(cat "$logs/$name.secs" 2>/dev/null || echo 0)" "${log#"$root"/}"
  if [ "$rc" != 0 ]; then
    failed_suites+=("$name")
    { tail -n 40 "$log"; echo; } | sed 's/^/   | /'  # the log may end without a newline
  fi
}

# suite NAME KIND WHERE CMD...: run it now and report it
suite() {
  local name="$1" kind="$2" where="$3"
  shift 3
  run_suite "$name" "$where" "$@"
  report "$name" "$kind"
}

pytest_opts=(-p no:cacheprovider -n 2 --dist loadfile --durations=10)
suite lint plain host .venv/bin/ruff check .
BSPLINECAM_REQUIRE_ALL=1 suite core-venv pytest host .venv/bin/python -m pytest "${pytest_opts[@]}" tests
BSPLINECAM_REQUIRE_ALL=0 BSPLINECAM_KERNELS=numpy suite core-debian pytest host /usr/bin/python3 -m pytest "${pytest_opts[@]}" \
  -m "not venv_only" tests

export BSPLINECAM_REQUIRE_ALL=1  # FreeCAD suites: a missing OpenCAMLib or rs274 fails, never skips
fc_modules=()
for m in "${FREECAD_MODULES[@]}"; do
  [ "$m" = TestBSplineCAMMigration ] || fc_modules+=("$m")
done
fc10="$root/tools/freecad-chroot.sh 1.0 freecadcmd"
fc11="$root/tools/freecad-chroot.sh 1.1 freecadcmd"

# documents saved by each FreeCAD, opened by the newer ones (TestBSplineCAMMigration): oldest first
migration_chain() {
  local rc=0
  rm -rf "$root/build/migration"
  echo "## FreeCAD 0.20"
  tools/run_freecad_tests.sh TestBSplineCAMMigration || rc=1
  echo "## FreeCAD 1.0"
  FREECADCMD="$fc10" tools/run_freecad_tests.sh TestBSplineCAMMigration || rc=1
  echo "## FreeCAD 1.1"
  FREECADCMD="$fc11" tools/run_freecad_tests.sh TestBSplineCAMMigration || rc=1
  return "$rc"
}
gui_chroot() {  # gui_chroot VERSION: run_gui_test.sh in that chroot's FreeCAD
  BSPLINECAM_DOCS="$root/build/screenshots-$1" tools/freecad-chroot.sh "$1" run \
    env FREECAD=/usr/bin/freecad QT_QPA_PLATFORM=xcb "$root/tools/run_gui_test.sh"
}

# Two lanes.  No two freecadcmd of one version run together (a chroot's FreeCADs share one HOME
# and user.cfg; the GUIs have their own): freecad-1.0 waits for the migration chain.
echo "   (FreeCAD suites: two lanes at a time; their lines follow when both lanes are done)"
(
  run_suite migration all migration_chain
  run_suite freecad-0.20 host tools/run_freecad_tests.sh "${fc_modules[@]}"
  FREECADCMD="$fc11" run_suite freecad-1.1 1.1 tools/run_freecad_tests.sh "${fc_modules[@]}"
) &
lane_a=$!
(
  run_suite gui host tools/run_gui_test.sh
  while [ ! -e "$logs/migration.rc" ] && kill -0 "$lane_a" 2>/dev/null; do sleep 2; done
  FREECADCMD="$fc10" run_suite freecad-1.0 1.0 tools/run_freecad_tests.sh "${fc_modules[@]}"
  run_suite gui-1.0 1.0 gui_chroot 1.0
  run_suite gui-1.1 1.1 gui_chroot 1.1
) &
lane_b=$!
wait "$lane_a" "$lane_b"
report migration unittest
for v in 0.20 1.0 1.1; do report "freecad-$v" unittest; done
for name in gui gui-1.0 gui-1.1; do report "$name" unittest; done

if [ "${#failed_suites[@]}" -gt 0 ]; then
  echo "failed suites: ${failed_suites[*]}"
fi
echo "${total_pass} passed, ${total_fail} failed"
[ "$total_fail" = 0 ]
