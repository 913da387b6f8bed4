"""The errors a user can cause (a bad file, a wrong skeleton, a bad spec, no data, an
output that cannot be written) and their one line of text: what the command line, the
app and batch workers report instead of a traceback."""

from __future__ import annotations


class ClusterError(Exception):
    """A Dask cluster that cannot be reached at the address the user gave."""


class NameNotFoundError(KeyError):
    """A name the user gave (a clip id, a joint) that is not there, or names several; a
    KeyError, as a lookup's. A KeyError of any other kind is a fault, not the user's."""


def user_errors() -> tuple[type[BaseException], ...]:
    """The exception types whose message is meant for the user."""
    from .core.humanoid import HumanoidError
    from .corruption import CorruptionSpecError
    from .data import DataNotFoundError
    from .engine import EngineError
    from .io import MotionFileError, OutputFileError

    return (
        MotionFileError,
        OutputFileError,
        EngineError,
        CorruptionSpecError,
        DataNotFoundError,
        HumanoidError,
        ClusterError,
        NameNotFoundError,
    )


def describe(err: BaseException) -> str:
    """One line for the user: a user error's message (a name not found without the
    quotes a KeyError's str() adds), else the exception's type and message."""
    if isinstance(err, NameNotFoundError) and err.args:
        return str(err.args[0])
    if isinstance(err, user_errors()):
        return str(err)
    return f"{type(err).__name__}: {err}"
