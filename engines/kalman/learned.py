"""``kalman-learned``: a data-driven Kalman filter whose system matrices are learnt from clean
training motion (Lou and Chai 2010, §4.2: their third baseline, "a simple data-driven
algorithm, which learns the system matrices from the same set of training data").

The model, for every non-root joint with rotation channels, with x_t its 3 unwrapped Euler
angles (deg) at frame t and the state ``s_t = (x_t, x_{t-1})``::

    x_{t+1} = A1 x_t + A2 x_{t-1} + c + w_t,   w_t ~ N(0, Q)
    y_t     = x_t + e_t,   e_t ~ N(0, diag r),  skipped where the joint is missing

smoothed exactly (Rauch-Tung-Striebel means) by :func:`~engines.kalman.coupled.coupled_smooth`.

Fitting (:meth:`LearnedKalman.fit`, on clean clips of one frame rate):

* dynamics by ridge least squares on the training clips, in acceleration form
  ``x_{t+1} - 2 x_t + x_{t-1} = Bx (x_t - mean) + Bv (x_t - x_{t-1}) + w`` (ridge
  ``DYNAMICS_RIDGE`` x the regressors' mean variance, shrinking towards constant velocity),
  so ``A1 = 2I + Bx + Bv``, ``A2 = -(I + Bv)``, ``c = -Bx mean``;
* the process covariance of the residual ``w``, per joint (3 x 3), for both the fitted
  dynamics and the constant-velocity model (``Bx = Bv = 0``: the covariance of the
  joint's angular accelerations).

Cleaning: the measurement variances r, like the overall size of each channel's process
noise, come from the observation exactly as in ``kalman`` (median absolute second
difference; SURE); the learnt part is the *shape* of Q, its correlation matrix ``C``,
shrunk towards the identity by ``correlation_shrinkage``: ``Q = S ((1-a) C + a I) S`` with
``S = diag(sqrt(q_kalman))``. With ``learned_dynamics`` the fitted A1, A2, c replace the
constant-velocity ones. The root position and rotation, and channels constant in the
observation, are cleaned by ``kalman``; beyond an angle channel's first and last observation
its smoothed value there is held, as in ``kalman``.

Choices (the paper does not give its model): per joint, not one full-body model (a small state
and few parameters to fit from a few thousand frames, and a gap, a whole joint missing, never
splits a state); constant velocity by default (the fitted dynamics' mean reversion towards the
training subjects' pose and their damping do not transfer to other performers); the clip's own
noise scales, as in ``kalman`` (the training scale does not fit another clip's motion), with
only the within-joint correlation learnt, half shrunk by default.

History and results: docs/engines/kalman.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from workbench.core.channels import unwrap_deg
from workbench.core.motion import Motion, Observation, joint_angle_columns
from workbench.engine import CleanResult, Engine, EngineError, EngineInfo
from workbench.engine.signal import prepare

from .coupled import coupled_smooth
from .filters import hold_angle_ends, smooth_channels

#: ridge on the dynamics regression, relative to the regressors' mean variance
DYNAMICS_RIDGE = 1e-2


def _model_joints(motion: Motion) -> np.ndarray:
    """Non-root joints with rotation channels: the joints the learnt model covers."""
    has_rot = motion.skeleton.has_rotation
    return np.array([j for j in range(1, motion.skeleton.n_joints) if has_rot[j]], dtype=int)


def _correlation(Q: np.ndarray) -> np.ndarray:
    """(G, 3, 3) correlation matrices of covariances ``Q``; channels without variance
    get an identity row and column."""
    d = np.sqrt(np.clip(np.einsum("gii->gi", Q), 0.0, None))
    ok = d > 1e-12
    dd = np.where(ok, d, 1.0)
    C = Q / dd[:, :, None] / dd[:, None, :]
    both = ok[:, :, None] & ok[:, None, :]
    eye = np.broadcast_to(np.eye(3), C.shape)
    return np.where(both, C, eye)


class LearnedKalman(Engine):
    """Data-driven Kalman filter: per-joint linear dynamics and process covariance
    learnt from clean motion, RTS smoother, noise levels from the observation."""

    @dataclass(frozen=True)
    class Params:
        #: weight of the identity in the process-noise correlation (0 = as learnt, 1 = ``kalman``)
        correlation_shrinkage: float = 0.5
        #: use the least-squares dynamics A1, A2, c instead of constant velocity
        learned_dynamics: bool = False

        def __post_init__(self) -> None:
            if not (math.isfinite(self.correlation_shrinkage) and 0.0 <= self.correlation_shrinkage <= 1.0):
                raise ValueError(f"correlation_shrinkage must be in [0, 1], got {self.correlation_shrinkage}")

    info = EngineInfo(
        name="kalman-learned",
        summary="data-driven Kalman filter: per-joint dynamics and process covariance learnt from clean motion",
        tasks=frozenset({"denoise", "fill"}),
        trainable=True,
        citation="Lou and Chai 2010 §4.2 (data-driven Kalman filter baseline)",
    )

    def __init__(self, params=None) -> None:
        super().__init__(params)
        self.joints_: np.ndarray | None = None
        self.mean_: np.ndarray | None = None  # (G, 3) mean pose of the modelled joints
        self.A1_: np.ndarray | None = None  # (G, 3, 3)
        self.A2_: np.ndarray | None = None  # (G, 3, 3)
        self.offset_: np.ndarray | None = None  # (G, 3)
        self.Q_fit_: np.ndarray | None = None  # (G, 3, 3) residual covariance of the fitted dynamics
        self.Q_cv_: np.ndarray | None = None  # (G, 3, 3) covariance of the accelerations
        self.n_frames_: int = 0

    # -- training -------------------------------------------------------------------
    def fit(self, motions: Sequence[Motion], /) -> "LearnedKalman":
        motions = self.training_motions(motions)
        joints = _model_joints(motions[0])
        cols = joint_angle_columns(joints)
        G = joints.size
        clips = [unwrap_deg(m.channels[:, cols]).reshape(m.n_frames, G, 3) for m in motions if m.n_frames >= 3]
        if not clips:
            raise EngineError("engine 'kalman-learned': the training motions need at least 3 frames each")
        mean = np.concatenate(clips).mean(axis=0)  # (G, 3)
        reg = np.concatenate([np.concatenate([x[1:-1] - mean, x[1:-1] - x[:-2]], axis=2) for x in clips])
        acc = np.concatenate([x[2:] - 2.0 * x[1:-1] + x[:-2] for x in clips])  # (N, G, 3)
        N = acc.shape[0]
        A1, A2 = np.zeros((G, 3, 3)), np.zeros((G, 3, 3))
        offset, Q_fit = np.zeros((G, 3)), np.zeros((G, 3, 3))
        Q_cv = np.einsum("ngi,ngj->gij", acc, acc) / N
        eye = np.eye(3)
        for g in range(G):
            R, T = reg[:, g], acc[:, g]  # (N, 6), (N, 3)
            live = np.concatenate([R[:, :3].std(axis=0) > 1e-9] * 2)
            B = np.zeros((3, 6))
            if live.any():
                Rl = R[:, live]
                gram = Rl.T @ Rl
                ridge = DYNAMICS_RIDGE * np.trace(gram) / live.sum()
                B[:, live] = np.linalg.solve(gram + ridge * np.eye(live.sum()), Rl.T @ T).T
                B[~live[:3], :] = 0.0
            Bx, Bv = B[:, :3], B[:, 3:]
            A1[g], A2[g] = 2.0 * eye + Bx + Bv, -(eye + Bv)
            offset[g] = -Bx @ mean[g]
            E = T - R @ B.T
            Q_fit[g] = E.T @ E / N
        self.joints_, self.mean_ = joints, mean
        self.A1_, self.A2_, self.offset_, self.Q_fit_, self.Q_cv_ = A1, A2, offset, Q_fit, Q_cv
        self.n_frames_ = int(sum(x.shape[0] for x in clips))
        self.fitted_on(motions[0])
        return self

    # -- fitted state ---------------------------------------------------------------
    def state_arrays(self) -> dict[str, np.ndarray]:
        self.require_fitted()
        return {
            "joints": self.joints_,
            "mean": self.mean_,
            "A1": self.A1_,
            "A2": self.A2_,
            "offset": self.offset_,
            "Q_fit": self.Q_fit_,
            "Q_cv": self.Q_cv_,
            "n_frames": np.array(self.n_frames_),
        }

    def load_state_arrays(self, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> None:
        try:
            self.joints_ = np.asarray(arrays["joints"], int)
            self.mean_, self.A1_, self.A2_ = arrays["mean"], arrays["A1"], arrays["A2"]
            self.offset_, self.Q_fit_, self.Q_cv_ = arrays["offset"], arrays["Q_fit"], arrays["Q_cv"]
            self.n_frames_ = int(arrays["n_frames"])
        except KeyError as err:
            raise EngineError(f"engine 'kalman-learned': the weights lack {err}; retrain the engine") from None
        G = self.joints_.size
        for name, shape in (
            ("mean", (G, 3)),
            ("A1", (G, 3, 3)),
            ("A2", (G, 3, 3)),
            ("offset", (G, 3)),
            ("Q_fit", (G, 3, 3)),
            ("Q_cv", (G, 3, 3)),
        ):
            if np.shape(arrays[name]) != shape:
                raise EngineError(
                    f"engine 'kalman-learned': weights array {name!r} has shape "
                    f"{np.shape(arrays[name])}, expected {shape}; retrain the engine"
                )

    # -- cleaning -------------------------------------------------------------------
    def clean(self, observation: Observation, /) -> CleanResult:
        """Clean the take in the engine's view of it (:meth:`model_view`: body-rooted, at the
        rate its dynamics were learnt at) and put the result back on the take."""
        view = self.model_view(observation)
        return view.restore(self._clean(view.observation))

    def _clean(self, observation: Observation) -> CleanResult:
        motion = observation.motion
        p = prepare(observation)
        Y, (q, r) = smooth_channels(p.bridged, p.mask)  # kalman for every channel
        F = motion.n_frames
        obs_j = observation.observed[:, self.joints_]  # (F, G)
        use = obs_j.sum(axis=0) >= 3
        if F >= 3 and use.any():
            g_idx = np.flatnonzero(use)
            cols = joint_angle_columns(self.joints_[g_idx]).reshape(-1, 3)  # (g, 3)
            qg, rg = q[cols], r[cols]
            live = qg > 0  # not constant in the observation
            if self.params.learned_dynamics:
                A1, A2, c, Q = self.A1_[g_idx], self.A2_[g_idx], self.offset_[g_idx], self.Q_fit_[g_idx]
            else:
                n = g_idx.size
                A1 = np.broadcast_to(2.0 * np.eye(3), (n, 3, 3))
                A2 = np.broadcast_to(-np.eye(3), (n, 3, 3))
                c, Q = np.zeros((n, 3)), self.Q_cv_[g_idx]
            a = self.params.correlation_shrinkage
            C = (1.0 - a) * _correlation(Q) + a * np.eye(3)
            both = live[:, :, None] & live[:, None, :]
            C = np.where(both, C, np.eye(3))
            s = np.sqrt(np.where(live, qg, 1.0))
            Qinv = np.linalg.inv(C) / s[:, :, None] / s[:, None, :]
            rg = np.where(live, rg, 1.0)
            Xg = p.bridged[:, cols].transpose(1, 0, 2)  # (g, F, 3)
            Mg = np.repeat(obs_j[:, g_idx].T[:, :, None], 3, axis=2)
            Z = coupled_smooth(Xg, Mg, rg, A1, A2, c, Qinv)  # (g, F, 3)
            Z = Z.transpose(1, 0, 2)
            keep = live.ravel()
            flat_cols = cols.ravel()[keep]
            Y[:, flat_cols] = Z.reshape(F, -1)[:, keep]
        return CleanResult(motion.with_channels(p.output(hold_angle_ends(Y, p.mask, motion.skeleton))))
