"""The constant-velocity smoother of a bank of channels and the estimator of its noise
variances: the numerics of the ``kalman`` engine, of ``mssa``'s smoothness prior and of
the motion-image autoencoders' anchor to the observation; and, built on
them, what IK keeps of an observation for the engines that clean joint positions
(:func:`ik_reference`: ``cae`` and its baselines, ``mssa``'s position mode) and which
holes the smoother of the angles bridges best (:func:`angles_bridge_holes`: ``cae``).

The model, per channel, in frames (``dt = 1``)::

    state       s_t = (x_t, v_t),   v_t = x_t - x_{t-1}
    dynamics    s_{t+1} = [[1, 1], [0, 1]] s_t + (1, 1) w_t,   w_t ~ N(0, q)
    measurement y_t = x_t + e_t,   e_t ~ N(0, r),   skipped where y_t is missing

i.e. the velocity takes a random step ``w_t`` every frame, so the second difference
``x_{t+1} - 2 x_t + x_{t-1}`` of the true signal is white with variance ``q``. Its
Rauch-Tung-Striebel smoothed mean is the minimiser of the posterior's negative log

    sum_observed (y_t - x_t)^2 / r + sum_t (x_{t+1} - 2 x_t + x_{t-1})^2 / q

a symmetric positive-definite pentadiagonal system in x (the initial state has a flat,
improper prior: it is fixed by the data, as in a diffusely initialised filter).
:func:`cv_smooth` solves it exactly for all channels at once, which gives the RTS
means to rounding (tests compare it with the forward-filter/backward-smoother
recursion) without a Python loop over frames:

* channels observed at every frame: ``(I + lambda D2'D2) x = y`` with ``lambda = r/q``.
  ``D2'D2 = L^2 - u u' - w w'`` where ``L`` is the free-ends (Neumann) Laplacian, which
  the orthonormal DCT-II diagonalises, and ``u = e_0 - e_1``, ``w = e_{F-1} - e_{F-2}``;
  so x is one DCT, a per-frequency gain ``1 / (1 + lambda mu_k^2)``, a rank-2
  Woodbury correction and one inverse DCT;
* channels with gaps: one banded Cholesky solve (LAPACK ``pbsv``) of all of them
  stacked one after another (uncoupled), for each channel's departure from the
  least-squares line through its observed samples (``D2`` takes lines to 0, so the system
  is the same; near ``q / r = 0``, a channel at rest seen in a few frames close together,
  the departure is what stays accurate); where Cholesky still fails, the line itself,
  the solution's limit as ``q / r`` goes to 0.


The position engines' parameters, shared by the helpers below :func:`smooth_joint_angles`:
``skeleton`` the take's skeleton; ``channels`` (F, D) its channel matrix, gaps bridged
(degrees and file units); ``observed`` (F, J) the joints' observed mask; ``positions``
(F, J, 3) joint positions by FK of the channels, in file units (only differences between
joints are used, so any common offset, e.g. the root's, may be taken off); ``step`` its
frames per captured frame (:attr:`workbench.core.motion.Observation.capture_step`; noise
is measured on the captured frames, :func:`measurement_variance`), 1 by default.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy.linalg import LinAlgError, solveh_banded

from ..core.channels import interpolate_gaps
from ..core.kinematics import short_lever_joints
from ..core.motion import angle_joints, angle_slice, joint_angle_columns

__all__ = [
    "R_FLOOR",
    "LAMBDA_GRID",
    "cv_smooth",
    "second_difference_band",
    "measurement_variance",
    "smoothing_ratio",
    "estimate_noise",
    "smooth_and_fill",
    "smooth_observed",
    "smooth_joint_angles",
    "OUTLIER_VARIANCE_RATIO",
    "angle_noise",
    "angle_and_position_noise",
    "HOLE_NOISE_CM",
    "POSITION_NOISE_FLOOR_CM",
    "angles_bridge_holes",
    "angles_are_quiet",
    "ik_reference",
]

#: smallest measurement variance (channel units squared): data are trusted to ~1e-5
R_FLOOR = 1e-10
#: candidate smoothing ratios lambda = r / q for the risk minimisation (log grid, x1.78)
LAMBDA_GRID = np.logspace(-2.0, 8.0, 41)
_MAD_TO_STD = 1.482602218505602


def cv_smooth(Y: np.ndarray, observed: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """RTS-smoothed positions of the constant-velocity model above, channel by channel.

    Solved exactly: by DCT for the channels observed at every frame (F >= 4), by one
    banded Cholesky solve for the others (the module docstring: about their lines, which a
    system too ill-conditioned for Cholesky returns). A channel with fewer than two
    observations is returned constant (its observed value, or 0).

    Parameters
    ----------
    Y : ndarray, shape (F, D)
        Measurements, in the channels' units (degrees, file units); anything where
        missing.
    observed : ndarray of bool, shape (F, D)
        True where ``Y`` is observed.
    q : ndarray, shape (D,), or float
        Process variances (of the second difference per frame), in channel units^2
        (deg^2, file units^2); > 0.
    r : ndarray, shape (D,), or float
        Measurement variances, in channel units^2; > 0.

    Returns
    -------
    ndarray, shape (F, D)
        The smoothed positions ``x_t``; across gaps, the model's path.
    """
    Y = np.asarray(Y, float)
    F, D = Y.shape
    observed = np.asarray(observed, bool)
    q = np.broadcast_to(np.asarray(q, float), (D,))
    r = np.broadcast_to(np.asarray(r, float), (D,))
    n_obs = observed.sum(axis=0)
    out = np.empty((F, D))
    few = np.flatnonzero(n_obs < 2)
    if few.size:
        out[:, few] = np.where(observed[:, few], Y[:, few], 0.0).sum(axis=0)
    complete = n_obs == F
    full = np.flatnonzero(complete & (n_obs >= 2)) if F >= 4 else np.zeros(0, int)
    gappy = np.setdiff1d(np.flatnonzero(n_obs >= 2), full)
    if full.size:
        out[:, full] = _smooth_complete(Y[:, full], r[full] / q[full])
    if gappy.size:
        out[:, gappy] = _smooth_banded(Y[:, gappy], observed[:, gappy], q[gappy], r[gappy])
    return out


def _smooth_complete(Y: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Exact solution of ``(I + lam D2'D2) x = y`` per column (F >= 4) by DCT + Woodbury.

    For speed the problem is solved on ``F' = F + p`` frames when that is a fast DCT
    length and ``p <= 3``: the ``p`` extra frames are unobserved, so they only continue
    the solution linearly and leave it unchanged on the first F frames; removing their
    data term is another rank-p correction.
    """
    F, D = Y.shape
    n = sfft.next_fast_len(F)
    if n - F > 3:
        n = F
    m = 2 + n - F
    mu = 2.0 - 2.0 * np.cos(np.pi * np.arange(n) / n)  # eigenvalues of the Laplacian L
    h = 1.0 / (1.0 + (mu**2)[:, None] * lam[None, :])  # (n, D) gains of A^-1 = (I + lam L^2)^-1
    # M = A - V S V':  V = [u, w, e_F, .., e_{n-1}],  S = diag(lam, lam, 1, .., 1)
    V = np.zeros((n, m))
    V[0, 0], V[1, 0], V[-1, 1], V[-2, 1] = 1.0, -1.0, 1.0, -1.0
    V[np.arange(F, n), np.arange(2, m)] = 1.0
    Cv = sfft.dct(V, type=2, norm="ortho", axis=0)  # (n, m)
    Yp = Y if n == F else np.concatenate([Y, np.zeros((n - F, D))])
    hY = h * sfft.dct(Yp, type=2, norm="ortho", axis=0)
    # Woodbury: M^-1 y = A^-1 y + A^-1 V (S^-1 - V'A^-1 V)^-1 V'A^-1 y
    i, j = np.triu_indices(m)
    g = (Cv[:, i] * Cv[:, j]).T @ h  # (pairs, D)
    G = np.empty((D, m, m))
    G[:, i, j] = g.T
    G[:, j, i] = g.T
    G = -G
    sinv = np.ones((D, m))
    sinv[:, :2] = (1.0 / lam)[:, None]
    G[:, np.arange(m), np.arange(m)] += sinv
    t = (Cv.T @ hY).T  # (D, m)
    c = np.linalg.solve(G, t[:, :, None])[:, :, 0]  # (D, m)
    hY += h * (Cv @ c.T)
    return sfft.idct(hY, type=2, norm="ortho", axis=0)[:F]


def second_difference_band(F: int) -> np.ndarray:
    """``D2'D2`` (F, F), D2 the second-difference operator, as a lower band of ``solveh_banded``.

    Its last entries of the sub-diagonals are 0, so the bands of several channels laid
    end to end (``(3, D, F)`` reshaped to ``(3, D F)``) form one banded system whose
    channels do not couple.

    Parameters
    ----------
    F : int
        The number of frames.

    Returns
    -------
    ndarray, shape (3, F)
        The lower band of ``scipy.linalg.solveh_banded`` (``band[i - j, j] = A[i, j]``):
        the diagonal, then the first and second sub-diagonals. All 0 for F < 3.
    """
    band = np.zeros((3, F))
    if F >= 3:
        band[0, :-2] += 1.0
        band[0, 1:-1] += 4.0
        band[0, 2:] += 1.0
        band[1, :-2] -= 2.0
        band[1, 1:-1] -= 2.0
        band[2, :-2] += 1.0
    return band


#: unknowns per banded solve (32 bytes each with the band): a long take's columns a few at
#: a time, the same values as one solve of all of them (their systems do not couple)
BANDED_UNKNOWNS = 1 << 20


def _smooth_banded(Y: np.ndarray, observed: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Exact solution of ``(W/r + D2'D2/q) x = W y / r`` per column (at least two observed
    samples each) by banded Cholesky, as many columns a solve as :data:`BANDED_UNKNOWNS`
    allows: the module docstring."""
    F, D = Y.shape
    out = np.empty((F, D))
    band, per_solve = second_difference_band(F), max(1, BANDED_UNKNOWNS // max(F, 1))
    for c in range(0, D, per_solve):
        cols = np.arange(c, min(c + per_solve, D))
        try:
            out[:, cols] = _solve_banded(band, Y[:, cols], observed[:, cols], q[cols], r[cols])
        except LinAlgError:  # one column at a time, to find those that fail
            for k in cols:
                try:
                    out[:, k] = _solve_banded(band, Y[:, [k]], observed[:, [k]], q[[k]], r[[k]])[:, 0]
                except LinAlgError:
                    out[:, k] = _observed_lines(Y[:, [k]], observed[:, [k]])[:, 0]
    return out


def _solve_banded(band: np.ndarray, Y: np.ndarray, observed: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(F, n): the solve of :func:`_smooth_banded` for the n columns of ``Y`` (F, n) at once,
    for their departures from :func:`_observed_lines`."""
    F = Y.shape[0]
    lines = _observed_lines(Y, observed)
    ir = 1.0 / r
    ab = band[:, None, :] * (1.0 / q)[None, :, None]  # (3, n, F)
    ab[0] += observed.T * ir[:, None]
    b = np.where(observed, Y - lines, 0.0).T * ir[:, None]  # (n, F)
    x = solveh_banded(
        ab.reshape(3, -1), b.reshape(-1), overwrite_ab=True, overwrite_b=True, lower=True, check_finite=False
    )
    return lines + x.reshape(-1, F).T


def _observed_lines(Y: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """(F, n): each column's least-squares line through its observed samples of ``Y`` (F, n),
    at least two each; row by row of the transposes, so a column's line has the same bits
    whatever columns come with it."""
    y, w = np.ascontiguousarray(Y.T), np.ascontiguousarray(observed.T)  # (n, F)
    t = np.arange(y.shape[1], dtype=float)
    n = w.sum(axis=1)
    t_mean = np.where(w, t, 0.0).sum(axis=1) / n
    y_mean = np.where(w, y, 0.0).sum(axis=1) / n
    dt = np.where(w, t - t_mean[:, None], 0.0)
    slope = (dt * np.where(w, y - y_mean[:, None], 0.0)).sum(axis=1) / (dt * dt).sum(axis=1)
    return (y_mean[:, None] + slope[:, None] * (t - t_mean[:, None])).T


def measurement_variance(Y: np.ndarray, observed: np.ndarray, robust: bool = True, *, step: float = 1.0) -> np.ndarray:
    """Per-channel white-noise variance from the second differences over fully observed triples.

    For white noise of variance r the second difference has variance 6 r, and a smooth
    120 fps signal contributes little to it.

    Channels resampled up from their capture (``step`` > 1) are measured on the frames
    nearest the captured ones (every ``step``-th): the frames between are interpolated,
    and the second differences of a line are 0, so all frames would show next to no
    noise. The variance returned is then per frame of ``Y``, ``step`` times the captured
    frames': taken as independent measurements, ``step`` frames of ``Y`` then carry the
    information of one captured frame (the interpolated noise's spectrum below the
    capture's Nyquist frequency, where a smoother's cut lies, is that flat level).

    Parameters
    ----------
    Y : ndarray, shape (F, D)
        Channels, in their units (degrees, file units); anything where missing.
    observed : ndarray of bool, shape (F, D)
        True where ``Y`` is observed.
    robust : bool
        True: from the second differences' median absolute value, robust to outliers and
        to the signal's occasional sharp accelerations, and exact for Gaussian noise, but
        low for noise with heavier tails (joint positions under angle noise: half the
        true variance on some rows). False: from their mean square, right for any noise,
        but it counts the signal's accelerations and every outlier.
    step : float
        Frames of ``Y`` per captured frame (:attr:`workbench.core.motion.Observation.capture_step`),
        at least 1.

    Returns
    -------
    ndarray, shape (D,)
        Variances in channel units^2 (deg^2, file units^2), at least :data:`R_FLOOR`.
        Channels with no observed triple (all of them when F < 3) get :data:`R_FLOOR`.
    """
    Y = np.asarray(Y, float)
    if step > 1.0:
        captured = np.unique(np.round(np.arange(0.0, Y.shape[0] - 1 + 1e-9, step)).astype(int))
        return step * measurement_variance(Y[captured], np.asarray(observed)[captured], robust)
    F, D = Y.shape
    if F < 3:
        return np.full(D, R_FLOOR)
    d2 = Y[2:] - 2.0 * Y[1:-1] + Y[:-2]  # (F-2, D)
    ok = observed[2:] & observed[1:-1] & observed[:-2]
    if not robust:  # summed down the (F, D) layout as it lies: 4x faster than along its transpose
        d2[~ok] = 0.0
        mean_square = np.einsum("fd,fd->d", d2, d2) / np.maximum(ok.sum(axis=0), 1)
        return np.maximum(mean_square / 6.0, R_FLOOR)
    # each channel's differences contiguous, partitioned in place: a median along the
    # frames of the (F, D) layout reads memory D numbers apart (the same medians, 3x slower)
    d2, ok = np.ascontiguousarray(np.abs(d2).T), ok.T  # (D, F-2)
    if ok.all():
        med = np.median(d2, axis=1, overwrite_input=True)
    else:
        # second differences touching a missing sample are replaced alternately by -1 and
        # +inf: the median then stays that of the valid ones (to within one rank)
        missing = np.ascontiguousarray(~ok)
        odd = np.cumsum(missing, axis=1) % 2 == 1
        d2[missing & odd] = np.inf
        d2[missing & ~odd] = -1.0
        med = np.median(d2, axis=1, overwrite_input=True)
        med = np.where(ok.any(axis=1) & np.isfinite(med), np.maximum(med, 0.0), 0.0)
    return np.maximum((_MAD_TO_STD * med) ** 2 / 6.0, R_FLOOR)


def smoothing_ratio(Y: np.ndarray, r: np.ndarray, observed_fraction: np.ndarray | float = 1.0) -> np.ndarray:
    """Per-channel ``lambda = r / q`` minimising Stein's unbiased estimate of the smoother's risk.

    The estimate is of the smoother's mean squared error, in the frequency domain.
    Away from the ends the smoother is the linear filter ``H(w) = 1 / (1 + lambda (2 - 2
    cos w)^2)``; with the periodogram ``P(w)`` of the channel (gap-free, e.g. bridged,
    after removing the line through its first and last samples so that its periodic
    extension has no jump), SURE(lambda) = mean_w (1 - H)^2 P + 2 r_eff mean_w H - r_eff,
    with ``r_eff = r * observed_fraction`` (bridged samples carry no noise). The minimiser
    over :data:`LAMBDA_GRID` is taken per channel.

    Parameters
    ----------
    Y : ndarray, shape (N, D)
        Gap-free channels (e.g. bridged), in their units (degrees, file units).
    r : ndarray, shape (D,)
        Measurement variances, in channel units^2 (:func:`measurement_variance`).
    observed_fraction : ndarray, shape (D,), or float
        The fraction of each channel's samples that are observed, in [0, 1].

    Returns
    -------
    ndarray, shape (D,)
        Values of :data:`LAMBDA_GRID`; its smallest for every channel when N < 4.
    """
    Y = np.asarray(Y, float)
    N, D = Y.shape
    if N < 4:
        return np.full(D, LAMBDA_GRID[0])
    t = np.arange(N, dtype=float)[:, None] / (N - 1)
    Z = Y - (Y[:1] + (Y[-1:] - Y[:1]) * t)  # starts and ends at 0: pad with zeros
    n = sfft.next_fast_len(N, real=True)
    spec = sfft.rfft(np.ascontiguousarray(Z.T), n=n, axis=1)  # (D, K)
    P = (spec.real**2 + spec.imag**2) / n  # sum_k w_k P_k = ||Z||^2
    K = P.shape[1]
    w = np.full(K, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    omega = 2.0 * np.pi * np.arange(K) / n
    g = (2.0 - 2.0 * np.cos(omega)) ** 2
    H = 1.0 / (1.0 + LAMBDA_GRID[:, None] * g[None, :])  # (L, K)
    fit = ((1.0 - H) ** 2 * w) @ P.T / N  # (L, D)
    dof = (H * w).sum(axis=1) / n  # (L,) mean gain
    r_eff = np.asarray(r, float) * observed_fraction
    risk = fit + 2.0 * r_eff[None, :] * dof[:, None]
    return LAMBDA_GRID[np.argmin(risk, axis=0)]


def estimate_noise(Y: np.ndarray, observed: np.ndarray, *, step: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Process and measurement variances ``(q, r)`` of every channel of a bridged channel matrix.

    ``r`` from :func:`measurement_variance`, ``q = r / lambda`` with ``lambda`` from
    :func:`smoothing_ratio`.

    Parameters
    ----------
    Y : ndarray, shape (F, D)
        A channel matrix with its gaps interpolated, in its units (degrees, file units).
    observed : ndarray of bool, shape (F, D)
        True where ``Y`` is observed.
    step : float
        Frames of ``Y`` per captured frame (:func:`measurement_variance`).

    Returns
    -------
    q : ndarray, shape (D,)
        Process variances for :func:`cv_smooth`, in channel units^2 (deg^2, file units^2).
    r : ndarray, shape (D,)
        Measurement variances, in channel units^2.
    """
    observed = np.asarray(observed, bool)
    r = measurement_variance(Y, observed, step=step)
    lam = smoothing_ratio(Y, r, observed.mean(axis=0))
    return r / lam, r


def smooth_and_fill(Y: np.ndarray, observed: np.ndarray, *, step: float = 1.0) -> np.ndarray:
    """Channels smoothed by :func:`cv_smooth` at the noise they show, gaps filled by the smoother.

    The noise variances are those :func:`estimate_noise` finds in the ``observed``
    samples (with the gaps bridged linearly for it); the gaps are filled with the
    constant-velocity model's path across them.

    Parameters
    ----------
    Y : ndarray, shape (F, D)
        Channels, in their units (degrees, file units); anything where missing.
    observed : ndarray of bool, shape (F, D)
        True where ``Y`` is observed.
    step : float
        Frames of ``Y`` per captured frame (:func:`measurement_variance`).

    Returns
    -------
    ndarray, shape (F, D)
        A new array; 0 in a column with no observation.
    """
    bridged = interpolate_gaps(Y, observed)
    return cv_smooth(bridged, observed, *estimate_noise(bridged, observed, step=step))


def smooth_observed(Y: np.ndarray, observed: np.ndarray, *, step: float = 1.0) -> np.ndarray:
    """:func:`smooth_and_fill` but bridged linearly across the gaps (between the smoothed ends).

    Parameters
    ----------
    Y, observed, step
        As in :func:`smooth_and_fill`.

    Returns
    -------
    ndarray, shape (F, D)
        The smoothed channels at the observed samples; in a gap the line between the
        smoothed samples around it, the nearest one held before a column's first and
        after its last observation.
    """
    return interpolate_gaps(smooth_and_fill(Y, observed, step=step), observed)


def smooth_joint_angles(
    channels: np.ndarray,
    observed: np.ndarray,
    joints: np.ndarray,
    smoothed: np.ndarray | None = None,
    *,
    step: float = 1.0,
) -> np.ndarray:
    """A copy of a channel matrix with the angles of ``joints`` smoothed where they are observed.

    The angles are smoothed by :func:`smooth_observed` where the joints are
    ``observed`` and bridged linearly across their holes; the other columns are copied.

    Parameters
    ----------
    channels : ndarray, shape (F, D)
        A channel matrix, gaps bridged: degrees and file units, the layout of
        :attr:`workbench.core.motion.Motion.channels` (D = 3 + 3J without translated
        joints).
    observed : ndarray of bool, shape (F, J)
        The joints' observed mask.
    joints : ndarray of int, shape (n,)
        The joints whose angles to smooth.
    smoothed : ndarray, shape (F, D), optional
        The channels' :func:`smooth_and_fill`, when the caller has it.
    step : float
        Frames per captured frame (:func:`measurement_variance`).

    Returns
    -------
    ndarray, shape (F, D)
        A new array.
    """
    out = np.array(channels, float)
    cols = joint_angle_columns(joints)
    mask = np.repeat(np.asarray(observed, bool)[:, joints], 3, axis=1)
    out[:, cols] = interpolate_gaps(
        smooth_and_fill(out[:, cols], mask, step=step) if smoothed is None else smoothed[:, cols], mask
    )
    return out


#: the mean square of the angles' second differences above this many times their
#: median-based estimate means outliers (Gaussian noise: 0.8-1.9 on the test split;
#: 5 % outliers of 3-6 stds: 3.3-9.3)
OUTLIER_VARIANCE_RATIO = 3.0


def _first_aimed(skeleton, joints: np.ndarray) -> np.ndarray:
    """The first aimed descendant of each of ``joints`` (n,): the one each is measured at."""
    return np.array([skeleton.aimed_descendants[j][0][0] for j in joints], int)


def _angle_variance(
    channels: np.ndarray, observed: np.ndarray, joints: np.ndarray, robust: bool, step: float
) -> np.ndarray:
    """The noise variance of each observed angle of ``joints`` (n, 3), degrees^2 per captured
    sample (:func:`measurement_variance`)."""
    seen = np.repeat(observed[:, joints], 3, axis=1)  # (F, 3n)
    variance = measurement_variance(channels[:, joint_angle_columns(joints)], seen, robust, step=step) / step
    return variance.reshape(len(joints), 3)


def _as_seen_by_descendant(skeleton, joints: np.ndarray, angle_variance: np.ndarray) -> np.ndarray:
    """Angle variances (n, 3, degrees^2) as the first aimed descendant of each joint sees them:
    the mean over the three angles, in rad^2, times the lever^2 (file units^2)."""
    lever2 = np.deg2rad(1.0) ** 2 * np.sum(skeleton.offsets[_first_aimed(skeleton, joints)] ** 2, axis=1)
    return angle_variance.mean(axis=1) * lever2


def angle_noise(
    skeleton, channels: np.ndarray, observed: np.ndarray, joints: np.ndarray, robust: bool = True, *, step: float = 1.0
) -> np.ndarray:
    """The noise of the observed angles of ``joints`` as the descendant each is aimed at sees it.

    Their variance in rad^2 per captured sample (:func:`measurement_variance`, the mean
    over a joint's three angles) times the lever^2: the squared offset of the joint's
    first aimed descendant (:attr:`workbench.core.skeleton.Skeleton.aimed_descendants`).

    Parameters
    ----------
    skeleton, channels, observed, step
        The take: see *The position engines' parameters* in the module docstring.
    joints : ndarray of int, shape (n,)
        Joints each aimed at a descendant at least (the first is measured).
    robust : bool
        False: from the mean square, which counts outliers (:func:`measurement_variance`).

    Returns
    -------
    ndarray, shape (n,)
        Variances in file units^2.

    Raises
    ------
    IndexError
        A joint aimed at no descendant.
    """
    return _as_seen_by_descendant(skeleton, joints, _angle_variance(channels, observed, joints, robust, step))


def angle_and_position_noise(
    skeleton, channels: np.ndarray, observed: np.ndarray, positions: np.ndarray, joints: np.ndarray, step: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The noise of ``joints`` as their descendants see it, through the angles and the positions,
    per captured sample; and the noise of each of their angles.

    Parameters
    ----------
    skeleton, channels, observed, positions, step
        The take: see *The position engines' parameters* in the module docstring.
    joints : ndarray of int, shape (n,)
        Joints each aimed at a descendant at least (the first is measured).

    Returns
    -------
    angle : ndarray, shape (n,)
        Through the observed angles (:func:`angle_noise`), in file units^2.
    heavy : ndarray, shape (n,)
        The same from the mean square (it counts outliers), in file units^2.
    position : ndarray, shape (n,)
        In the descendant's observed position seen from the joint (where both are
        observed; :func:`measurement_variance`, the mean over x, y, z), in file units^2.
    angles : ndarray, shape (n, 3)
        Of each observed angle of the joints (``angle`` before it is seen from the
        descendant), in degrees^2.
    """
    children = _first_aimed(skeleton, joints)
    n = len(joints)
    relative = (positions[:, children] - positions[:, joints]).reshape(len(positions), 3 * n)
    both = np.repeat(observed[:, joints] & observed[:, children], 3, axis=1)
    angles = _angle_variance(channels, observed, joints, True, step)
    return (
        _as_seen_by_descendant(skeleton, joints, angles),
        angle_noise(skeleton, channels, observed, joints, False, step=step),
        measurement_variance(relative, both, step=step).reshape(n, 3).mean(axis=1) / step,
        angles,
    )


def _quieter(angle: np.ndarray, heavy: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Which joints are better told by their observed angles than by the observed
    positions, from :func:`angle_and_position_noise`'s measures (n,): those whose angles'
    noise, as the moved descendant sees it, is below the noise of the descendant's
    position seen from the joint, and whose angles carry no outliers (the smoother would
    pass them; :data:`OUTLIER_VARIANCE_RATIO`). Noise in the angles (as inertial capture
    has) favours the angles: the relative position carries the noise of every joint
    above; noise on the positions (markers) does not."""
    return (angle < position) & (heavy < OUTLIER_VARIANCE_RATIO * angle)


#: outliers or position noise below this std (cm), as a joint's descendant sees them,
#: still leave a take's holes to the angles' smoother (:func:`angles_bridge_holes`; under
#: ``spatial`` noise ``cae``'s errors cross between 0.4 and 0.5 cm); angles noisier than
#: this are no longer quiet (:func:`angles_are_quiet`)
HOLE_NOISE_CM = 0.5


#: position noise (cm, a descendant's seen from its joint) below which a take's noise is
#: not taken to be in its positions (:func:`_noise_is_in_positions`): a clean take's own
#: accelerations reach it at 30 fps (Bandai validation: median 0.03, 90th percentile 0.18 cm),
#: ``spatial:0.1`` 0.11-0.42 cm
POSITION_NOISE_FLOOR_CM = 0.15


#: the mean over a take's measured joints of log(angle noise / position noise) above which
#: its noise is taken to be in its positions (:func:`_noise_is_in_positions`): the middle of
#: the gap between angle and position noise on the validation takes
POSITION_NOISE_LOG_RATIO = 0.3


def _noise_is_in_positions(skeleton, angle: np.ndarray, position: np.ndarray) -> bool:
    """Whether a take's noise is in its positions, from :func:`angle_and_position_noise`'s
    measures (n,) of :func:`_measured_joints`: the mean over the joints of log(angle /
    position) is above :data:`POSITION_NOISE_LOG_RATIO`, and the median position noise
    above :data:`POSITION_NOISE_FLOOR_CM`.

    Under angle noise every joint's relative position carries the noise of the joints
    above it, so the ratio is small; under position noise the angles, solved from the
    positions, carry all of it and their twist besides. Bandai validation and CMU
    train takes (seed 0, as ``cae`` sees them): -6.9 to -0.05 under ``angular`` 0.1-0.5
    (outliers included), 0.68 to 1.85 under ``spatial`` 0.2-1; the threshold lies
    midway. At 0, its earlier value, a Mixamo retarget of CMU 124_01 at 30 fps (+0.03)
    and a Z-up export in inches (+0.11) were taken for position noise under
    ``angular:0.5``, and their feet aimed at noisy toes: the universal mssa missed the
    Mixamo take's left foot by 20.8 degrees (`docs/universal.md`, *Takes from other
    exporters*). The median of each measure, compared, called 4 % of the Bandai takes
    under ``angular:0.5`` (12 % under 0.1) position noise: their arm and neck angles
    carry their twist's noise too. A clean take's measures are its motion's
    accelerations (a ratio either side of 1): its angles, as good as they come, are kept.
    """
    floor = (POSITION_NOISE_FLOOR_CM / skeleton.unit_cm) ** 2
    return bool(np.mean(np.log(angle / position)) > POSITION_NOISE_LOG_RATIO and np.median(position) > floor)


def _measured_joints(skeleton, observed: np.ndarray, short_lever_cm: float) -> np.ndarray:
    """The joints whose noise tells a take's: aimed at one descendant beyond
    ``short_lever_cm`` and observed somewhere."""
    short = short_lever_joints(skeleton, short_lever_cm)
    return np.array(
        [
            j
            for j in range(1, skeleton.n_joints)
            if len(skeleton.aimed_descendants[j]) == 1 and j not in short and observed[:, j].any()
        ],
        int,
    )


def _take_noise(
    skeleton, channels: np.ndarray, observed: np.ndarray, positions: np.ndarray, short_lever_cm: float, step: float
) -> tuple[float, float, float] | None:
    """A take's noise as its descendants see it: the medians over :func:`_measured_joints`
    of :func:`angle_and_position_noise`'s (angle, heavy, position); None when no joint
    can be measured."""
    joints = _measured_joints(skeleton, observed, short_lever_cm)
    if not joints.size:
        return None
    angle, heavy, position, _ = angle_and_position_noise(skeleton, channels, observed, positions, joints, step)
    return float(np.median(angle)), float(np.median(heavy)), float(np.median(position))


def angles_bridge_holes(
    skeleton,
    channels: np.ndarray,
    observed: np.ndarray,
    positions: np.ndarray,
    short_lever_cm: float,
    step: float = 1.0,
) -> bool:
    """Whether a take's holes are better bridged by the smoother of their angles than from positions.

    The holes are better bridged by the constant-velocity smoother of their angles than
    filled from the joint positions around them unless the angles carry outliers (the
    smoother would pass them; :data:`OUTLIER_VARIANCE_RATIO`) or the noise is in the
    positions (the descendants' position noise below the angles'), each only where it
    exceeds :data:`HOLE_NOISE_CM`. So a clean take passes (its measures are the motion's
    own accelerations, 0.02-0.07 cm), and so does angle noise, but not position noise
    of more than 0.5 cm. The measures are medians over :func:`_measured_joints` (the
    joints aimed at one descendant beyond ``short_lever_cm`` and observed somewhere) of
    those of :func:`angle_and_position_noise`.

    Parameters
    ----------
    skeleton, channels, observed, positions, step
        The take: see *The position engines' parameters* in the module docstring.
    short_lever_cm : float
        Joints whose aimed descendants all lie within this many cm are not measured.

    Returns
    -------
    bool
        False also when no joint can be measured.
    """
    noise = _take_noise(skeleton, channels, observed, positions, short_lever_cm, step)
    if noise is None:
        return False
    angle, heavy, position = noise
    floor = (HOLE_NOISE_CM / skeleton.unit_cm) ** 2
    outliers = heavy > max(OUTLIER_VARIANCE_RATIO * angle, floor)
    return not (outliers or floor < position < angle)


def angles_are_quiet(skeleton, channels: np.ndarray, observed: np.ndarray, short_lever_cm: float = 5.0) -> bool:
    """Whether a take's angles carry less noise than :data:`HOLE_NOISE_CM`, outliers included.

    The noise is :func:`angle_noise` from the mean square, as a descendant sees it: the
    median over :func:`_measured_joints` (the joints aimed at one descendant beyond
    ``short_lever_cm`` and observed somewhere). Test split: a clean take passes
    (0.02-0.08 cm, the motion's own accelerations), and so do ``angular:0.1``
    (0.09-0.26 cm) and ``spatial:0.2`` (0.36-0.42); ``spatial:0.3`` (0.54-0.63), most
    ``angular:0.5`` takes and outliers do not.

    Parameters
    ----------
    skeleton, channels, observed
        The take: see *The position engines' parameters* in the module docstring.
    short_lever_cm : float
        Joints whose aimed descendants all lie within this many cm are not measured
        (the default, 5 cm, leaves out CMU's hands and finger bases).

    Returns
    -------
    bool
        False also when no joint can be measured.
    """
    joints = _measured_joints(skeleton, observed, short_lever_cm)
    if not joints.size:
        return False
    heavy = np.median(angle_noise(skeleton, channels, observed, joints, robust=False))
    return bool(heavy < (HOLE_NOISE_CM / skeleton.unit_cm) ** 2)


def ik_reference(
    skeleton,
    channels: np.ndarray,
    observed: np.ndarray,
    positions: np.ndarray,
    short_lever_cm: float,
    angle_lever_cm: float,
    smoothed: np.ndarray | None = None,
    step: float = 1.0,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """What IK keeps of an observation when an engine has cleaned its joint positions.

    For :func:`workbench.core.kinematics.inverse_kinematics`: the reference angles, and
    its keyword arguments that say how to keep them: the joints it keeps at the
    reference in every frame, the frames in which some more joints keep it, and the
    frames in which a joint aimed at one direction takes the twist whose Euler angles
    are nearest the reference's.

    Parameters
    ----------
    skeleton, channels, observed, positions, step
        The take: see *The position engines' parameters* in the module docstring.
    short_lever_cm : float
        The joints whose aimed descendants all lie within this many cm and that are
        observed somewhere are kept at the reference in every frame (a few mm of
        position error turn a 3-cm lever by tens of degrees).
    angle_lever_cm : float
        The other joints whose aimed descendants all lie within this many cm (but the
        root chain's) keep the reference where they are observed, where their angles
        are quieter than the positions (:func:`_quieter`, at their first aimed
        descendant), in takes whose noise is not in the positions
        (:func:`_noise_is_in_positions`) and carries no outliers (the median of the
        measured joints' :data:`OUTLIER_VARIANCE_RATIO`). With several descendants
        (a chest aimed at the neck and the shoulders) the network's few mm of error at
        each turn the whole joint.
    smoothed : ndarray, shape (F, D), optional
        The channels' :func:`smooth_and_fill`, when the caller has it (at ``step``).

    Returns
    -------
    reference : ndarray, shape (F, J, 3)
        The reference angles, in degrees: the observed angles of every joint of
        :func:`workbench.core.motion.angle_joints` (all with a rotation but the root
        chain) smoothed by :func:`smooth_joint_angles`, the others' as in ``channels``.
        The twist about single-child bones and the leaves come from them.
    ik : dict
        ``reference_joints``, ndarray of int (k,): the joints kept at the reference in
        every frame (``short_lever_cm``). ``reference_frames``, ndarray of bool (F, J):
        the frames in which each joint keeps the reference (``angle_lever_cm``); False
        throughout for the other joints. ``reference_measured``, ndarray of bool (F, J):
        where the take's noise is in its angles, their
        observed frames (there the reference is the observation smoothed, its Euler
        angles noisy each alone, and the twist nearest them is the likeliest); False
        throughout where the noise is in the positions (the median over the joints aimed
        at one descendant beyond ``short_lever_cm`` of :func:`angle_and_position_noise`),
        whose angles, solved from them, carry it as a turn of the bone, not of its twist.
        Validation, 1 seed, the turn in every observed frame against the smallest rotation:
        ``angular:0.5`` on Bandai, ``cae`` 3.70 -> 3.52 degrees, ``mssa:space=positions``
        3.97 -> 3.74; but ``spatial:0.5``, ``mssa:space=positions`` 2.57 -> 2.72.
        ``aim_variance``, ndarray (J,), and ``reference_variance``, ndarray (J, 3): in takes
        whose noise is in their angles and carries no outliers, for the joints measured
        (aimed at one descendant beyond ``short_lever_cm``, and the levers), the noise of
        the observed position of the aimed descendant seen from the joint (file
        units^2) and of the joint's observed angles (:func:`measurement_variance`,
        degrees^2), both per captured sample; NaN and 0 elsewhere. IK weighs the
        smoothed angles against the aim by them. Each is the observation's noise, not
        the reference's or the engine's error: both smooth, by about as much. Validation,
        1 seed, ``angular:0.5``, ``cae``, rms_angle_deg / mpjpe_cm: Bandai 2.461 / 2.110
        -> 2.291 / 2.048, CMU train 1.859 / 1.239 -> 1.733 / 1.188; the aim variance
        scaled by 0.1, 0.3, 1 and 3 gave Bandai 2.324 / 2.065, 2.310 / 2.053, 2.291 /
        2.048, 2.285 / 2.070.
    """
    short = short_lever_joints(skeleton, short_lever_cm, observed)
    reference = smooth_joint_angles(channels, observed, angle_joints(skeleton), smoothed, step=step)
    reference = reference[:, angle_slice(skeleton)].reshape(positions.shape)
    frames = np.zeros(observed.shape, bool)
    reference_variance = np.zeros((skeleton.n_joints, 3))
    aim_variance = np.full(skeleton.n_joints, np.nan)
    measured = _measured_joints(skeleton, observed, short_lever_cm)
    levers = np.setdiff1d(short_lever_joints(skeleton, angle_lever_cm, observed), [*short, *skeleton.root_chain])
    in_angles = False  # the take's noise is not in its positions
    if measured.size:
        joints = np.union1d(measured, levers)  # each measured once
        angle, heavy, position, angles = angle_and_position_noise(skeleton, channels, observed, positions, joints, step)
        of_take = np.isin(joints, measured)
        in_angles = not _noise_is_in_positions(skeleton, angle[of_take], position[of_take])
        if in_angles and np.median(heavy[of_take]) < OUTLIER_VARIANCE_RATIO * np.median(angle[of_take]):
            quiet = joints[np.isin(joints, levers) & _quieter(angle, heavy, position)]
            frames[:, quiet] = observed[:, quiet]
            aim_variance[joints] = position
            reference_variance[joints] = angles
    return reference, {
        "reference_joints": short,
        "reference_frames": frames,
        "reference_measured": observed & in_angles,
        "reference_variance": reference_variance,
        "aim_variance": aim_variance,
    }
