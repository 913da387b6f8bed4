"""Shared machinery for the engines built on PyTorch (CPU build): seeding, thread
count, converting a module's state to plain arrays and back (so weights are stored by
:mod:`workbench.engine.weights` as a checksummed ``.npz`` and never unpickled), and a training
progress bar.

Import this module only inside ``fit``/``clean``/``load_state_arrays`` so that listing
engines does not import torch.
"""

from __future__ import annotations

import os
import random
import warnings
from contextlib import contextmanager
from typing import Iterable, Iterator, Mapping

import numpy as np
import torch

from .base import EngineError

__all__ = [
    "seed_everything",
    "reproducible_training",
    "torch_threads",
    "bf16_is_native",
    "default_threads",
    "module_arrays",
    "load_module_arrays",
    "progress",
]

#: the elementwise functions ATen computes with MKL's vector math library (VML) on
#: contiguous float32 and float64 tensors (``aten/src/ATen/cpu/vml.h``)
VML_FUNCTIONS = (
    torch.acos, torch.asin, torch.atan, torch.cos, torch.erf, torch.erfc, torch.erfinv, torch.exp,
    torch.log, torch.log10, torch.log2, torch.sin, torch.sqrt, torch.tan, torch.tanh, torch.trunc,
)  # fmt: skip


def settle_vml() -> None:
    """Call every :data:`VML_FUNCTIONS` once, on one thread, in both float types.

    VML chooses each function's code for this CPU on the function's first call. When
    that first call is torch's two threads at once, one thread can compute its half
    with other code, whose last bits differ: ebf's first clean of a process came out
    different in the second half of a 2-minute take's frames in about one process in
    four (up to 0.009 degrees; the encoder's first ``tanh``), while every later clean
    gave the usual bits. Calling each function first on a few numbers, which torch
    does not split across threads, settles the choice before any take is cleaned
    (measured: 16 processes of 16 then gave the usual bits). Runs when this module is
    imported; a few hundred microseconds.
    """
    for dtype in (torch.float32, torch.float64):
        x = torch.full((16,), 0.5, dtype=dtype)
        for function in VML_FUNCTIONS:
            function(x)


settle_vml()


def seed_everything(seed: int) -> torch.Generator:
    """Seed python, numpy and torch; return a torch Generator seeded the same way.

    Parameters
    ----------
    seed : int
        The seed (numpy's is ``seed % 2**32``).

    Returns
    -------
    torch.Generator
        A new generator seeded with ``seed``.
    """
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)
    return torch.Generator().manual_seed(seed)


@contextmanager
def reproducible_training(seed: int) -> Iterator[None]:
    """Run a training block seeded, on :func:`default_threads` torch threads, deterministically.

    The block is seeded with ``seed`` (:func:`seed_everything`) and runs on
    :func:`default_threads` torch threads with torch's deterministic algorithms; both
    are restored after (the seeded random states are not). Without them two-thread training is not repeatable:
    four one-epoch runs of ``workbench train ebf`` gave three different sets of weights
    (after 20 epochs, test ``angular:0.5`` 1.74 and 1.77 degrees, where seeds 0 and 1
    give 1.66 and 1.76 deterministically). With them two threads give bit for bit what
    one thread gives, about as fast. Holden's unpooling has no deterministic flag, but
    it puts each value in a place of its own (2-frame pooling), so it is deterministic
    anyway: warn only, and hush that warning.

    Parameters
    ----------
    seed : int
        The seed of python's, numpy's and torch's random generators.

    Yields
    ------
    None
    """
    before = torch.are_deterministic_algorithms_enabled(), torch.is_deterministic_algorithms_warn_only_enabled()
    seed_everything(seed)
    torch.use_deterministic_algorithms(True, warn_only=True)
    try:
        with torch_threads(default_threads()), warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="max_unpooling.*deterministic")
            yield
    finally:
        torch.use_deterministic_algorithms(before[0], warn_only=before[1])


@contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """Run the block on ``n`` torch threads, then restore the count.

    A streamed EBF frame is faster on one thread here (0.84 vs 1.16 ms: the 2-core
    machine spends more on synchronising two than it gains); a batch of motion images is
    faster on both (``cae``, four 256-frame views: 12.5 vs 6.9 ms).

    Parameters
    ----------
    n : int
        The number of torch threads (``torch.set_num_threads``), >= 1.

    Yields
    ------
    None
    """
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def bf16_is_native() -> bool:
    """Whether oneDNN runs bfloat16 on this CPU's own instructions.

    Native means AVX-512 BW/VL/DQ, with AMX or AVX512-BF16 at their best, or ARM's BF16.
    Elsewhere it emulates them, far slower than float32: on an AVX2-only AMD EPYC a 16-channel 3x3 convolution took 20x
    the float32 time (130x without channels_last), ``cae`` cleaned 0.6k frames/s
    instead of 3.5-4.5k, and training took 9x as long (54 s against 5.9 s for 32k
    frames; all of ``workbench train cae`` in float32: 29 minutes).

    Returns
    -------
    bool
        True when native; False when emulated, or in a torch build without oneDNN.
    """
    try:
        return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):  # a torch build without oneDNN
        return False


def default_threads() -> int:
    """The number of torch threads to run on: OMP_NUM_THREADS if set, else all cores, at most 2.

    Returns
    -------
    int
        At least 1. OMP_NUM_THREADS, when set and not empty, is taken as it is (not
        capped at 2).

    Raises
    ------
    ValueError
        OMP_NUM_THREADS is not a whole number.
    """
    return max(1, int(os.environ.get("OMP_NUM_THREADS") or min(2, os.cpu_count() or 1)))


def module_arrays(module: torch.nn.Module, prefix: str = "") -> dict[str, np.ndarray]:
    """The module's parameters and buffers as float32 numpy arrays, keyed ``prefix + name``.

    Parameters
    ----------
    module : torch.nn.Module
        The network.
    prefix : str
        Put before each ``state_dict`` name, to keep the module's arrays apart from
        others saved beside them (e.g. ``"net."``).

    Returns
    -------
    dict of str to ndarray
        New float32 arrays, on the CPU, of the ``state_dict``'s shapes (integer buffers
        too; :func:`load_module_arrays` casts them back).
    """
    return {prefix + k: v.detach().cpu().float().numpy() for k, v in module.state_dict().items()}


def load_module_arrays(module: torch.nn.Module, arrays: Mapping[str, np.ndarray], prefix: str = "") -> None:
    """Load arrays saved by :func:`module_arrays` into ``module``.

    Parameters
    ----------
    module : torch.nn.Module
        The network built from the manifest's parameters; its state is replaced.
    arrays : Mapping[str, ndarray]
        The saved arrays. Those whose names start with ``prefix`` must be exactly the
        module's (with the empty prefix: every array).
    prefix : str
        As given to :func:`module_arrays`.

    Raises
    ------
    EngineError
        A clear message when the names or shapes do not match the network.
    """
    state = module.state_dict()
    wanted = {prefix + k for k in state}
    have = {k for k in arrays if k.startswith(prefix)}
    if wanted != have:
        missing, extra = sorted(wanted - have)[:3], sorted(have - wanted)[:3]
        raise EngineError(
            f"weights do not fit this network (missing {missing}, unexpected {extra}); "
            "they were saved by another version or with other parameters"
        )
    new = {}
    for k, v in state.items():
        a = np.asarray(arrays[prefix + k])
        if a.shape != tuple(v.shape):
            raise EngineError(f"weights do not fit this network: {k} has shape {a.shape}, expected {tuple(v.shape)}")
        new[k] = torch.from_numpy(a.astype(np.float32)).to(v.dtype)
    module.load_state_dict(new)


def progress(iterable: Iterable, desc: str, total: int | None = None):
    """A tqdm progress bar on stderr (none in CI).

    Parameters
    ----------
    iterable : Iterable
        What the bar iterates over.
    desc : str
        The bar's label.
    total : int, optional
        The number of items, when ``len(iterable)`` does not say it.

    Returns
    -------
    tqdm.tqdm
        An iterable over ``iterable``, updating at most once a second; disabled when the
        environment variable ``CI`` is ``true``.
    """
    from tqdm import tqdm

    return tqdm(
        iterable, desc=desc, total=total, dynamic_ncols=True, mininterval=1.0, disable=os.environ.get("CI") == "true"
    )
