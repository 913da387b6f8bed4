"""Shared fixtures: real clips from the data root (../shared/data in CI).

Tests that read the team's data (through ``data_root`` and the fixtures built on it) skip,
saying why, on a machine that has none, where the data root falls back to the package's
embedded takes; under CI (``CI=true``) its absence fails them instead, so a CI run without
the data cannot pass by skipping. ``embedded_root`` is for tests that the embedded takes
serve."""

from __future__ import annotations

import os

# One torch thread per test process: two 2-thread torch processes on this 2-core machine
# slow each other down 20x. Headless rendering settings for VTK and Qt.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

import numpy as np
import pytest

from workbench.data import EMBEDDED_ROOT, catalogue, find_data_root, is_embedded
from workbench.io import read_bvh

# the plugin package's own tests run in tests/test_plugin.py, with the plugin installed
collect_ignore = ["plugin_engine"]


def pytest_collection_modifyitems(config, items):
    """The app's tests are ``gui``; the conformance suite's training checks ``slow``."""
    for item in items:
        if "app" in item.path.parent.parts[-1:]:
            item.add_marker(pytest.mark.gui)
        if item.nodeid.endswith("-fit]"):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def data_root():
    root = find_data_root()
    if is_embedded(root):
        why = "needs the team's data (../shared/data or $WORKBENCH_DATA): only the embedded takes are here"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI {why}")
        pytest.skip(why)
    return root


@pytest.fixture(scope="session")
def embedded_root():
    """The two CMU takes shipped in the package (walk/35_31 and jump/16_06)."""
    return EMBEDDED_ROOT


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
def studio_take(clips):
    """Bandai walk dataset-1 walk/active 001 (22 joints with six channels each, the Hips
    translated under the reference node joint_Root, 30 fps): 146 frames."""
    return next(c for c in clips if c.id == "bandai/walk/dataset-1_walk_active_001").load()


@pytest.fixture(scope="session")
def stretchy_take(studio_take):
    """The studio take with a stretchy rig's left forearm: LowerArm_L translated, its
    bone 10 % longer and shorter over a second, as a stretchy export would animate it."""
    sk = studio_take.skeleton
    k = sk.index("LowerArm_L")
    stretch = 1.0 + 0.1 * np.sin(2 * np.pi * np.arange(studio_take.n_frames) / studio_take.fps)
    translations = np.concatenate([studio_take.translations, (stretch[:, None] * sk.offsets[k])[:, None]], axis=1)
    return studio_take.replace(skeleton=sk.replace(translated=(*sk.translated, k)), translations=translations)


@pytest.fixture(scope="session")
def held_out_walk(clips):
    """CMU walk 35_31 of the test split (subject 35, held out of training): 421 frames."""
    return next(c for c in clips if c.id == "cmu/walk/35_31").load()
