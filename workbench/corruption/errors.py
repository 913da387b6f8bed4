"""Errors raised by the corruption models (no units involved)."""

from __future__ import annotations


class CorruptionSpecError(ValueError):
    """A corruption spec is malformed (unknown model name, wrong number of parameters, a
    non-number or an out-of-range value) or cannot be applied (see the subclass). Catch
    this one to report any corruption problem to a user."""


class CorruptionApplyError(CorruptionSpecError):
    """A well-formed spec cannot be applied to this clip or seed: a block longer than the
    clip allows, more joints than it has, a skeleton without wrists and ankles for
    ``spatial-ends``, a clean clip with non-finite values, a negative seed."""
