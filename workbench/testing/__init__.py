"""Conformance checks every engine must pass (used by the test suite over every
registered engine, and available to third-party engine authors)."""

from .conformance import (
    CHECKS,
    CheckSkipped,
    check_engine,
    conformance_clips,
    parametrize_with_engine_checks,
    quick_untrained,
    run_check,
)

__all__ = [
    "CHECKS",
    "CheckSkipped",
    "check_engine",
    "conformance_clips",
    "parametrize_with_engine_checks",
    "quick_untrained",
    "run_check",
]
