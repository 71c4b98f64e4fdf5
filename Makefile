# BSplineCAM: the two commands of the README.  Each installs what is missing first.
.PHONY: demo test setup bench lock fresh-check screenshots

# The main job: the case-study net to exported surface, G-code and its verification, in out/.
demo:
	tools/setup.sh
	tools/main_job.sh

# Every test suite (core in two numpys, FreeCAD 0.20, 1.0 and 1.1, the GUI under Xvfb in each).
test:
	tools/setup.sh --test
	tools/test.sh

setup:
	tools/setup.sh --test

bench:
	tools/setup.sh
	.venv/bin/python benchmarks/evaluate.py

# Re-pin every PyPI package of the venv (requirements-dev.txt -> requirements.lock), then test.
lock:
	tools/lock.sh
	$(MAKE) test

# What a new machine does: a fresh clone in a temporary folder, the README's two commands run
# there with every cache rebuilt (new venv, new chroots, a throw-away HOME for the addon link).
fresh-check:
	tools/fresh_check.sh

# Refresh the workbench's pictures in docs/ on purpose (the GUI tests in FreeCAD 0.20 under Xvfb;
# `make test` writes them to build/screenshots).
screenshots:
	tools/setup.sh --test
	BSPLINECAM_DOCS="$(CURDIR)/docs" tools/run_gui_test.sh
