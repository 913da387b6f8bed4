"""Input at the edges, with every registered engine: each take either cleans (a finite
motion of the same length) or gets an EngineError, never another exception; the reader
refuses what is no take with a MotionFileError naming the line."""

import numpy as np
import pytest

from workbench import registry
from workbench.core.motion import Observation
from workbench.data import find_clip
from workbench.engine import EngineError
from workbench.io import MotionFileError, read_bvh
from workbench.testing.takes import chain_bvh


@pytest.fixture(scope="module")
def walk(embedded_root):
    return find_clip("cmu/walk/35_31", embedded_root).load()


def snake_bvh(n_joints: int = 50, frames: int = 200) -> str:
    """A chain of ``n_joints`` joints 5 cm apart, waving: no humanoid at all."""
    return chain_bvh(n_joints, frames, bone=5.0, wave_deg=10.0)


def edge_takes(walk, tmp_path):
    takes = {f"{n} frames": walk.slice(0, n) for n in (1, 2, 3)}
    huge = walk.angles_deg.copy()
    huge[10, 5, 0] = 1e30
    takes["an angle of 1e30"] = walk.replace(angles_deg=huge)
    offsets = walk.skeleton.offsets.copy()
    offsets[walk.skeleton.index("LeftHand")] = 0.0
    takes["a zero-length bone"] = walk.replace(skeleton=walk.skeleton.replace(offsets=offsets))
    (tmp_path / "snake.bvh").write_text(snake_bvh())
    takes["a snake of 50 joints"] = read_bvh(tmp_path / "snake.bvh")
    return takes


@pytest.mark.slow
def test_every_engine_cleans_or_refuses_each_edge_take(walk, tmp_path):
    problems = []
    for what, take in edge_takes(walk, tmp_path).items():
        for spec in registry.available():
            try:
                cleaned = registry.create(spec).clean(Observation(take)).motion
            except EngineError as err:
                assert str(err), f"{spec} on {what}: an empty message"
                continue
            except Exception as err:  # the failure this test exists to catch
                problems.append(f"{spec} on {what}: {type(err).__name__}: {err}")
                continue
            if cleaned.n_frames != take.n_frames or not np.isfinite(cleaned.channels).all():
                problems.append(f"{spec} on {what}: a result of {cleaned.n_frames} frames, finite: "
                                f"{np.isfinite(cleaned.channels).all()}")  # fmt: skip
    assert not problems, "\n".join(problems)


@pytest.mark.slow
def test_a_take_of_100000_frames_cleans_with_the_classical_engines(walk):
    reps = -(-100_000 // walk.n_frames)
    long = walk.with_channels(np.tile(walk.channels, (reps, 1))[:100_000])
    for spec in ("gaussian", "butterworth", "kalman", "lerp>gaussian"):
        cleaned = registry.create(spec).clean(Observation(long)).motion
        assert cleaned.n_frames == 100_000 and np.isfinite(cleaned.channels).all(), spec


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda text: text.replace("Frame Time: 0.0333333", "Frame Time: 0"), "'Frame Time:' must be positive"),
        (lambda text: text.replace("Frame Time: 0.0333333", "Frame Time: -0.01"), "'Frame Time:' must be positive"),
        (lambda text: text.replace("JOINT j2", "JOINT j1"), "joint name 'j1' appears twice"),
        (lambda text: text.replace("Frames: 10", "Frames: 1000000000"), "'Frames:' says 1000000000 but only 10"),
    ],
)
def test_the_reader_refuses_frame_times_and_names_that_are_no_take(tmp_path, change, message):
    path = tmp_path / "take.bvh"
    path.write_text(change(snake_bvh(3, 10)))
    with pytest.raises(MotionFileError, match=message) as err:
        read_bvh(path)
    assert str(err.value).startswith(f"{path}:"), "the message names the file and line"
