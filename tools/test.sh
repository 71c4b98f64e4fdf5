#!/usr/bin/env bash
# SPDX-License-Identifier: LGPL-2.1-or-later
# Every test suite, in order; exits non-zero if any test failed.  Assumes tools/setup.sh --test.
#   lint         ruff on the whole tree
#   core-venv    pytest in the project venv (numpy 2.x, cadquery's OCCT, SciPy/geomdl references)
#   core-debian  pytest in Debian's python3 (numpy 1.24, the Python FreeCAD 0.20 runs)
#   freecad-0.20 unittest modules inside freecadcmd 0.20
#   freecad-1.0  the same modules inside freecadcmd 1.0 (Debian trixie chroot)
#   freecad-1.1  the same modules inside freecadcmd 1.1 (Debian sid chroot)
#   gui          the real FreeCAD 0.20 GUI under Xvfb (screenshots in docs/)
#   gui-1.0      the real FreeCAD 1.0 GUI under Xvfb in the chroot (build/screenshots-1.0/)
#   gui-1.1      the real FreeCAD 1.1 GUI under Xvfb in the chroot (build/screenshots-1.1/)
# Each log starts with the Debian versions of the packages that suite ran on (FreeCAD, OCCT,
# numpy, Qt bindings, rs274), so a change upstream shows in the log of the run it reached.
# The last line reads "N passed, N failed" over all tests run.
set -uo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
logs="$root/build/test-logs"
mkdir -p "$logs"
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
  echo "# Debian packages ($1):"
  if [ "$1" = host ]; then
    dpkg-query -W -f='${db:Status-Abbrev} ${Package} ${Version}\n' "${host_reported[@]}" 2>/dev/null | sed -n 's/^ii */#   /p'
  else
    tools/freecad-chroot.sh "$1" versions 2>/dev/null | sed 's/^/#   /'
  fi
}

# suite NAME KIND(pytest|unittest|plain) WHERE(host|1.0|1.1) CMD...
suite() {
  local name="$1" kind="$2" where="$3"
  shift 3
  local log="$logs/$name.log" rc p f start
  start=$(date +%s)
  printf '== %-13s ' "$name"
  versions "$where" >"$log"
  "$@" >>"$log" 2>&1
  rc=$?
  case "$kind" in
    pytest) read -r p f < <(count_pytest "$log") ;;
    unittest) read -r p f < <(count_unittest "$log") ;;
    *) if [ "$rc" = 0 ]; then p=1; f=0; else p=0; f=1; fi ;;
  esac
  if [ "$rc" != 0 ] && [ "$f" = 0 ]; then f=1; fi  # a crash that ran no test still fails
  total_pass=$((total_pass + p))
  total_fail=$((total_fail + f))
  printf '%4d passed, %d failed  (exit %d, %ds)  log: %s\n' "$p" "$f" "$rc" "$(( $(date +%s) - start ))" "${log#"$root"/}"
  if [ "$rc" != 0 ]; then
    failed_suites+=("$name")
    { tail -n 40 "$log"; echo; } | sed 's/^/   | /'  # the log may end without a newline
  fi
}

suite lint plain host .venv/bin/ruff check .
BSPLINECAM_REQUIRE_ALL=1 suite core-venv pytest host .venv/bin/python -m pytest -p no:cacheprovider tests
BSPLINECAM_REQUIRE_ALL=0 suite core-debian pytest host /usr/bin/python3 -m pytest -p no:cacheprovider tests
# documents saved by each FreeCAD, opened by the newer ones (TestBSplineCAMMigration)
rm -rf "$root/build/migration"
export BSPLINECAM_REQUIRE_ALL=1  # FreeCAD suites: a missing OpenCAMLib or rs274 fails, never skips
suite freecad-0.20 unittest host tools/run_freecad_tests.sh "${FREECAD_MODULES[@]}"
for v in 1.0 1.1; do
  FREECADCMD="$root/tools/freecad-chroot.sh $v freecadcmd" suite "freecad-$v" unittest "$v" \
    tools/run_freecad_tests.sh "${FREECAD_MODULES[@]}"
done
suite gui unittest host tools/run_gui_test.sh
for v in 1.0 1.1; do
  BSPLINECAM_DOCS="$root/build/screenshots-$v" suite "gui-$v" unittest "$v" \
    tools/freecad-chroot.sh "$v" run env FREECAD=/usr/bin/freecad QT_QPA_PLATFORM=xcb "$root/tools/run_gui_test.sh"
done

if [ "${#failed_suites[@]}" -gt 0 ]; then
  echo "failed suites: ${failed_suites[*]}"
fi
echo "${total_pass} passed, ${total_fail} failed"
[ "$total_fail" = 0 ]
