"""The shared torch helpers."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from engines.torch_support import torch_threads  # noqa: E402


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
