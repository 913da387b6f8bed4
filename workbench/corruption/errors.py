"""Errors raised by the corruption models (no units involved)."""

from __future__ import annotations


class CorruptionError(ValueError):
    """A corruption cannot be applied: a spec that does not fit the clip (a block longer
    than the clip, more joints than it has), a clip with non-finite values, a bad seed."""


class CorruptionSpecError(CorruptionError):
    """A corruption spec text (or a model's parameters) is malformed: unknown model name,
    wrong number of parameters, a non-number or an out-of-range value."""
