#!/usr/bin/env bash
# Run FreeCAD-layer unittest modules in FreeCAD's own Python and exit with their status.
#
# Usage:
#   tools/run_freecad_tests.sh [MODULE[.Class[.test]]...]   default: TestBSplineCAMFeature
# Environment:
#   FREECADCMD   the command-line FreeCAD to use (default: freecadcmd); for FreeCAD 1.0:
#                FREECADCMD="tools/freecad10.sh freecadcmd" tools/run_freecad_tests.sh
#
# `freecadcmd FILE` ignores the file's exit status, `freecadcmd -c CODE` returns sys.exit's,
# so the runner is passed as code.  Modules are looked up in tests/ (repo root on sys.path).
# After the unittest summary it prints the ten slowest tests (seconds, test id); a test's time
# runs from the end of the one before, so a class's setUpClass counts in its first test.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
if [[ $# -eq 0 ]]; then
    set -- TestBSplineCAMFeature
fi
for m in "$@"; do
    [[ "$m" =~ ^[A-Za-z_][A-Za-z0-9_.]*$ ]] || { echo "bad module name: $m" >&2; exit 2; }
done
MODULES="$(printf "'%s'," "$@")"
CODE="
import sys, time, unittest
sys.path[:0] = ['$ROOT/tests', '$ROOT']
suite = unittest.TestSuite()
for name in [$MODULES]:
    suite.addTests(unittest.defaultTestLoader.loadTestsFromName(name))
times, last = [], [time.perf_counter()]
class TimedResult(unittest.TextTestResult):
    def stopTest(self, test):  # time since the previous test ended: setUpClass counts in the first
        super().stopTest(test)
        now = time.perf_counter()
        times.append((now - last[0], test.id()))
        last[0] = now
result = unittest.TextTestRunner(verbosity=2, stream=sys.stdout, resultclass=TimedResult).run(suite)
print('slowest tests (s since the previous one ended, so a class set-up counts in its first test):')
for seconds, name in sorted(times, reverse=True)[:10]:
    print(f'{seconds:8.2f}  {name}')
sys.stdout.flush()
sys.exit(0 if result.wasSuccessful() and result.testsRun else 1)
"
read -r -a FC <<<"${FREECADCMD:-freecadcmd}"
exec "${FC[@]}" -c "$CODE"
