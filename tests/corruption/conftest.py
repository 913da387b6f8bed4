"""Shared clips for the corruption tests, read once per session."""

from __future__ import annotations

from pathlib import Path

import pytest

from workbench.io.bvh import read_bvh

DATA = Path("/work/shared/data")
WALK = DATA / "cmu/walk/02_01.bvh"  # 344 frames, 31 joints, CMU units
LONG = DATA / "cmu/walk/03_03.bvh"  # 4564 frames
DAZ = DATA / "cmu-daz/kick/10_01.bvh"  # 43 joints, cm


def _read(path: Path):
    if not path.exists():
        pytest.skip(f"test data not found: {path}")
    return read_bvh(path).slice(1)  # frame 0 is a T-pose


@pytest.fixture(scope="session")
def walk():
    return _read(WALK)


@pytest.fixture(scope="session")
def long_walk():
    return _read(LONG)


@pytest.fixture(scope="session")
def daz():
    return _read(DAZ)
