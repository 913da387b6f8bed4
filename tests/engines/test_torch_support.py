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


FIRST_CALL = """
import torch
import workbench.engine.torch_support  # settles VML when imported
torch.set_num_threads(2)
g = torch.Generator().manual_seed(0)
with torch.inference_mode():
    h = torch.nn.Linear(256, 256)(torch.rand(14400, 256, generator=g))  # the threads just busy
    first, second = torch.tanh(h), torch.tanh(h)
print(torch.equal(first, second))
"""


@pytest.mark.parametrize("process", range(3))
def test_the_first_threaded_vml_call_of_a_process_gives_the_usual_bits(process):
    """Without :func:`settle_vml` the first call of a process computed one thread's half
    with other code in about one process in five (ebf's encoder: a take's second half of
    frames came out different); three fresh processes catch that most of the time."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True"]
