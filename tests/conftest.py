"""Shared fixtures: real clips from the data root (../shared/data in CI)."""

from __future__ import annotations

import os

# One torch thread per test process: two 2-thread torch processes on this 2-core machine
# slow each other down 20x. Headless rendering settings for VTK and Qt.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

import pytest

from workbench.data import catalogue, find_data_root
from workbench.io import read_bvh


@pytest.fixture(scope="session")
def data_root():
    return find_data_root()


@pytest.fixture(scope="session")
def clips(data_root):
    return catalogue(data_root)


@pytest.fixture(scope="session")
def walk(data_root):
    """CMU walk 02_01 (31 joints, 120 fps), T-pose frame dropped: 343 frames."""
    return read_bvh(data_root / "cmu" / "walk" / "02_01.bvh").slice(1)


@pytest.fixture(scope="session")
def kick(data_root):
    """cmu-daz kick 10_03 (43 joints), reference frame dropped."""
    return read_bvh(data_root / "cmu-daz" / "kick" / "10_03.bvh").slice(1)


@pytest.fixture(scope="session")
def held_out_walk(clips):
    """CMU walk 35_31 of the test split (subject 35, held out of training): 421 frames."""
    return next(c for c in clips if c.id == "cmu/walk/35_31").load()
