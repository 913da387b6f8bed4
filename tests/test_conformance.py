"""Every registered engine passes the conformance suite of workbench.testing.

Trained engines use their committed weights; one without weights is fitted for one
epoch (when it has an ``epochs`` parameter) on short training takes: the suite checks
the protocol, not quality.
"""

import dataclasses

import pytest

from workbench import registry
from workbench.testing import CHECKS, check_engine, conformance_clips

_ready: dict = {}


@pytest.fixture(scope="module")
def takes(data_root):
    return conformance_clips(data_root, dataset="cmu")


@pytest.fixture(scope="module")
def training(clips):
    from workbench.data import select

    return [c.load().slice(0, 400) for c in select(clips, "train", dataset="cmu")[:4]]


def _engine(name, training):
    if name not in _ready:
        engine = registry.create(name)
        if engine.info.trainable and engine.skeleton_signature_ is None:
            if "epochs" in {f.name for f in dataclasses.fields(engine.Params)}:
                engine = registry.create(f"{name}:epochs=1", pretrained=False)
            engine.fit(training)
        _ready[name] = engine
    return _ready[name]


@pytest.mark.parametrize("name", registry.available())
@pytest.mark.parametrize("check", list(CHECKS))
def test_engine_conformance(name, check, takes, training):
    motion, foreign = takes
    check_engine(lambda: _engine(name, training), motion, foreign, checks=[check])
