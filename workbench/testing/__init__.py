"""Conformance checks every engine must pass (used by the test suite over every
registered engine, and available to third-party engine authors)."""

from .conformance import CHECKS, check_engine, conformance_clips

__all__ = ["CHECKS", "check_engine", "conformance_clips"]
