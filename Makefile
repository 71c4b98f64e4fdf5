# BSplineCAM: the two commands of the README.  Each installs what is missing first.
.PHONY: demo test setup bench

# The main job: the case-study net to exported surface, G-code and its verification, in out/.
demo:
	tools/setup.sh
	tools/main_job.sh

# Every test suite (core in two numpys, FreeCAD 0.20 and 1.0, the GUI under Xvfb).
test:
	tools/setup.sh --test
	tools/test.sh

setup:
	tools/setup.sh --test

bench:
	tools/setup.sh
	.venv/bin/python benchmarks/evaluate.py
