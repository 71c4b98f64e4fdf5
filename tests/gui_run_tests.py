# SPDX-License-Identifier: LGPL-2.1-or-later
"""Macro run by ``freecad tests/gui_run_tests.py`` (see tools/run_gui_test.sh).

Once FreeCAD's event loop runs, it runs the unittest modules named in BSPLINECAM_GUI_TESTS
(default TestBSplineCAMGui), writes the results to BSPLINECAM_GUI_OUT (JSON) and the runner's
text to the same path with ``.log``, and ends FreeCAD with exit status 0 only on success.
"""

from __future__ import annotations

import io
import json
import os
import sys
import traceback
import unittest
from pathlib import Path

from PySide import QtCore

TESTS = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd() / "tests"
OUT = Path(os.environ.get("BSPLINECAM_GUI_OUT", "/tmp/bsplinecam-gui.json"))
#: BSplineCAM modules FreeCAD's start-up imported (InitGui must import none: fast start).
os.environ["BSPLINECAM_STARTUP_MODULES"] = json.dumps(
    sorted(name for name in sys.modules if name.split(".")[0] == "BSplineCAM")
)


def run_tests() -> None:
    status = 1
    result_doc: dict = {"ok": False}
    stream = io.StringIO()
    try:
        for path in (str(TESTS), str(TESTS.parent)):
            if path not in sys.path:
                sys.path.insert(0, path)
        names = os.environ.get("BSPLINECAM_GUI_TESTS", "TestBSplineCAMGui").split()
        suite = unittest.defaultTestLoader.loadTestsFromNames(names)
        result = unittest.TextTestRunner(stream=stream, verbosity=2).run(suite)
        result_doc = {
            "ok": result.wasSuccessful() and result.testsRun > 0,
            "run": result.testsRun,
            "failures": [[str(t), tb] for t, tb in result.failures],
            "errors": [[str(t), tb] for t, tb in result.errors],
            "skipped": [[str(t), why] for t, why in result.skipped],
        }
        status = 0 if result_doc["ok"] else 1
    except BaseException:  # noqa: BLE001 - whatever happens, FreeCAD must exit with a status
        result_doc["errors"] = [["gui_run_tests", traceback.format_exc()]]
    try:
        OUT.write_text(json.dumps(result_doc, indent=1), encoding="utf-8")
        OUT.with_suffix(".log").write_text(stream.getvalue(), encoding="utf-8")
    finally:
        sys.stdout.flush()
        os._exit(status)  # FreeCAD's normal quit would ask to save the test documents


QtCore.QTimer.singleShot(500, run_tests)
