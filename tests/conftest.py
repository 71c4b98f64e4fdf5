# SPDX-License-Identifier: LGPL-2.1-or-later
"""Shared fixtures: the repository on sys.path and small reference nets."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

CASE_STUDY = ROOT / "examples" / "case-study.json"


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261123)


def random_net(rng: np.random.Generator, rows: int = 7, cols: int = 9) -> np.ndarray:
    """A wavy height-field net over a rows x cols grid, with jitter in x and y."""
    x, y = np.meshgrid(np.linspace(0, 60, rows), np.linspace(0, 40, cols), indexing="ij")
    z = 5 * np.sin(x / 9) * np.cos(y / 7) + rng.normal(scale=1.0, size=x.shape)
    net = np.stack([x, y, z], axis=-1)
    net[..., :2] += rng.normal(scale=0.5, size=net[..., :2].shape)
    return net

#: Modules that run inside FreeCAD (listed in freecad_modules.txt) or its GUI, not in pytest.
FREECAD_MODULES = [
    line.strip() + ".py"
    for line in (Path(__file__).parent / "freecad_modules.txt").read_text().splitlines()
    if line.strip() and not line.startswith("#")
]
collect_ignore = [*FREECAD_MODULES, "TestBSplineCAMGui.py", "gui_run_tests.py"]
