"""Every registered engine passes the conformance suite of workbench.testing.

Trained engines use their committed weights; one without weights is fitted with its
quick training options (``Engine.QUICK_FIT``) on short training takes: the suite checks
the protocol, not quality. A check that does not apply is reported as skipped, with
its reason.
"""

import pytest

from workbench import registry
from workbench.testing import conformance_clips, parametrize_with_engine_checks, quick_untrained, run_check

_ready: dict = {}


@pytest.fixture(scope="module")
def takes(data_root):
    return conformance_clips(data_root, dataset="cmu")


@pytest.fixture(scope="module")
def training(clips):
    from workbench.data import select

    return [c.load().slice(0, 200) for c in select(clips, "train", dataset="cmu")[:3]]


def _engine(name, training):
    if name not in _ready:
        engine = registry.create(name)
        if engine.info.trainable and engine.skeleton_signature_ is None:
            engine = quick_untrained(name)().fit(training)
        _ready[name] = engine
    return _ready[name]


@parametrize_with_engine_checks(registry.available())
def test_engine_conformance(engine, check, takes, training):
    motion, foreign = takes
    run_check(
        check,
        lambda: _engine(engine, training),
        motion,
        foreign=foreign,
        make_untrained=quick_untrained(engine),
        training=training,
    )
