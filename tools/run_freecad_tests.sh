#!/usr/bin/env bash
# Run FreeCAD-layer unittest modules in FreeCAD's own Python and exit with their status.
#
# Usage:
#   tools/run_freecad_tests.sh [MODULE...]        default: TestBSplineCAMFeature
# Environment:
#   FREECADCMD   the command-line FreeCAD to use (default: freecadcmd); for FreeCAD 1.0:
#                FREECADCMD="tools/freecad10.sh freecadcmd" tools/run_freecad_tests.sh
#
# `freecadcmd FILE` ignores the file's exit status, `freecadcmd -c CODE` returns sys.exit's,
# so the runner is passed as code.  Modules are looked up in tests/ (repo root on sys.path).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
if [[ $# -eq 0 ]]; then
    set -- TestBSplineCAMFeature
fi
for m in "$@"; do
    [[ "$m" =~ ^[A-Za-z_][A-Za-z0-9_]*$ ]] || { echo "bad module name: $m" >&2; exit 2; }
done
MODULES="$(printf "'%s'," "$@")"
CODE="
import sys, unittest
sys.path[:0] = ['$ROOT/tests', '$ROOT']
suite = unittest.TestSuite()
for name in [$MODULES]:
    suite.addTests(unittest.defaultTestLoader.loadTestsFromName(name))
result = unittest.TextTestRunner(verbosity=2, stream=sys.stdout).run(suite)
sys.stdout.flush()
sys.exit(0 if result.wasSuccessful() and result.testsRun else 1)
"
read -r -a FC <<<"${FREECADCMD:-freecadcmd}"
exec "${FC[@]}" -c "$CODE"
