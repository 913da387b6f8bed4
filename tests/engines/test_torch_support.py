"""The shared torch helpers."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from workbench.engine.torch_support import default_threads, reproducible_training, torch_threads  # noqa: E402


def test_torch_threads_sets_and_restores_the_count():
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        with torch_threads(1):
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
        with pytest.raises(RuntimeError), torch_threads(1):
            raise RuntimeError("restored on errors too")
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_reproducible_training_seeds_and_restores_the_settings():
    before = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    draws = []
    for _ in range(2):
        with reproducible_training(7):
            assert torch.are_deterministic_algorithms_enabled()
            assert torch.get_num_threads() == default_threads()
            draws.append(torch.rand(3))
        assert (torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()) == before
    assert torch.equal(*draws)
