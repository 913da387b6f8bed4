"""Deep recurrent mocap cleaning (Mall et al. 2017): ``ebf`` (Encoder-Bidirectional-
Filter denoiser, with ``bias`` and ``free`` variants and a streaming API), ``ebd``
(Encoder-Bidirectional-Decoder gap filler; ``ebd>ebf`` cleans noisy takes with gaps) and
the paper's ablations ``bf`` (no encoder) and ``nn`` (feed-forward over the window).

Modules: features (per-frame inputs, windows; numpy), nets (networks and the adaptive
filter; torch), training (the shared training loop), base (the shared engine class),
filters (EBF, BF, NN), ebd (EBD), stream (the streaming cleaner). Torch is imported only
when an engine is fitted, loaded or run. Weights: ``weights/<variant>/<dataset>/``.
"""

from .ebd import EBD
from .filters import BF, EBF, NN

__all__ = ["EBF", "EBD", "BF", "NN"]
