"""Kalman-filter engines: ``kalman`` (per-channel constant-velocity model, Lou and Chai's
general Kalman filter baseline) and ``kalman-learned`` (linear dynamics learnt from clean
motion, their data-driven Kalman filter baseline). A package so that the trained
engine's committed weights live in ``engines/kalman/weights/<variant>/<dataset>/``."""

from .filters import Kalman
from .learned import LearnedKalman

__all__ = ["Kalman", "LearnedKalman"]
