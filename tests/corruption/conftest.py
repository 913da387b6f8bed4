"""Clips for the corruption tests, read once per session (``walk``, CMU 02_01 without
its T-pose frame, comes from tests/conftest.py)."""

from __future__ import annotations

import pytest

from workbench.io.bvh import read_bvh


@pytest.fixture(scope="session")
def long_walk(data_root):
    """CMU walk 03_03: 4563 frames (T-pose frame dropped), 31 joints, CMU units."""
    return read_bvh(data_root / "cmu" / "walk" / "03_03.bvh").slice(1)


@pytest.fixture(scope="session")
def daz(data_root):
    """cmu-daz kick 10_01: 43 joints, lengths in cm (reference frame dropped)."""
    return read_bvh(data_root / "cmu-daz" / "kick" / "10_01.bvh").slice(1)
