"""The engine layer: what every cleaning method implements, built-in or third-party, and
the toolkit they share. Engines import from here and from the rest of the public
``workbench`` API, never from each other.

- :mod:`.base`: the :class:`Engine` base class, :class:`EngineInfo`, :class:`CleanResult`,
  the :class:`Pipeline` of ``a>b`` specs and the errors.
- :mod:`.signal`: preparing a channel matrix for a filter (unwrapped angles, bridged
  gaps) and putting the result back; Gaussian smoothing along time.
- :mod:`.smoothing`: the constant-velocity smoother and its noise estimates, and what
  IK keeps of an observation for the engines that clean positions.
- :mod:`.view`: a take as a trained engine models it (rooted at the body, at its
  weights' rate) and the way back.
- :mod:`.weights`: checksummed weights on disk, never pickled.
- :mod:`.threads`: numpy's BLAS on one thread beside torch; :mod:`.torch_support`:
  seeding, threads and state arrays for torch engines (imports torch: import it inside
  ``fit`` or ``clean`` only).
"""

from .base import (
    INFERENCE,
    SPACES,
    TASKS,
    TRAINED,
    TRAINING,
    WEIGHTS_OPTION,
    CleanResult,
    Engine,
    EngineError,
    EngineInfo,
    NotFittedError,
    Pipeline,
    param_roles,
    trained,
    training,
    with_humanoid_overrides,
)

__all__ = [
    "Engine",
    "EngineInfo",
    "CleanResult",
    "EngineError",
    "NotFittedError",
    "Pipeline",
    "TASKS",
    "SPACES",
    "WEIGHTS_OPTION",
    "trained",
    "training",
    "param_roles",
    "TRAINED",
    "TRAINING",
    "INFERENCE",
    "with_humanoid_overrides",
]
