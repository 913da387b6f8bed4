"""Every registered engine passes the conformance suite of workbench.testing."""

import pytest

from workbench import registry
from workbench.testing import CHECKS, check_engine, conformance_clips


@pytest.fixture(scope="module")
def takes(data_root):
    return conformance_clips(data_root)


@pytest.fixture(scope="module")
def training(clips):
    from workbench.data import select

    return [c.load().slice(0, 400) for c in select(clips, "train", dataset="cmu")[:4]]


@pytest.mark.parametrize("name", registry.available())
@pytest.mark.parametrize("check", list(CHECKS))
def test_engine_conformance(name, check, takes, training):
    motion, foreign = takes

    def make():
        engine = registry.create(name)
        if engine.info.trainable and engine.skeleton_signature_ is None:
            engine.fit(training)
        return engine

    check_engine(make, motion, foreign, checks=[check])
