"""numpy's BLAS runs on one thread while the torch engines clean (workbench.engine.threads)."""

import numpy as np
from threadpoolctl import threadpool_info

from workbench.corruption import parse_corruption
from workbench.engine.threads import one_blas_thread
from workbench.registry import create


def blas_threads() -> list[int]:
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


def test_one_blas_thread_inside_and_restored_after():
    before = blas_threads()
    assert before, "numpy's BLAS not found by threadpoolctl"
    seen = one_blas_thread(blas_threads)()
    assert seen == [1] * len(before)
    assert blas_threads() == before


def test_the_torch_engines_clean_on_one_blas_thread(monkeypatch, walk):
    import engines.cae.bodies as cae_bodies  # the IK of the cae family
    from engines.ebf import filters

    seen = []

    def recording(function):
        def call(*args, **kwargs):
            seen.append(blas_threads())
            return function(*args, **kwargs)

        return call

    monkeypatch.setattr(cae_bodies, "inverse_kinematics", recording(cae_bodies.inverse_kinematics))
    monkeypatch.setattr(filters, "rewrap_angles", recording(filters.rewrap_angles))
    obs = parse_corruption("angular:0.5").apply(walk.slice(0, 160), seed=0)
    for name in ("cae", "ebf"):
        assert np.isfinite(create(name).clean(obs).motion.channels).all()
    assert len(seen) == 2 and all(threads == [1] * len(threads) for threads in seen)
