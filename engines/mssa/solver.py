"""Robust filtering with M-SSA bases: the objective of Lou and Chai (2010), Eq. 11/16,
minimised by their alternating scheme (§3.4).

All arrays are in normalised channel units (see :mod:`engines.mssa`). With observations
y (F, L), observed flags alpha (F, L) in {0, 1}, bases E (L M, K) and windows z_s (the
M frames from s, flattened channel-major as in :mod:`.bases`), s = 0 .. F - M::

    J(z, c) = sum_{t,l} alpha rho(z - y) + lambda sum_s ||z_s - E c_s||^2
              [+ sum_l mu_l sum_t (z_{t+1,l} - 2 z_{t,l} + z_{t-1,l})^2]
    rho(r)  = p^2 / 2 (1 - exp(-r^2 / p^2))          (Welsch, Eq. 9)

The bracketed smoothness term (our addition, ``smoothness`` mu (L,), "cg" only) is the
prior of a per-channel constant-velocity Kalman smoother (velocity a random walk of
variance 1 / (2 mu_l) per frame).

Each iteration (i) sets every window's coefficients in closed form, c_s = E^T z_s
(Eq. 13); (ii) updates the motion with c fixed (Eq. 14), which separates into one
scalar problem per entry: with n_t the number of windows covering frame t and a_t the
sum of those windows' reconstructions of frame t (overlap-add of E c_s), an IRLS step
with weight w = alpha exp(-r^2 / p^2) (= phi(r)/r) minimises
``w r^2 / 2 + lambda (n_t z^2 - 2 z a_t)``, i.e. ``z = (w y + 2 lambda a_t) / (w + 2
lambda n_t)``. (Eq. 15 of the paper writes the data term as ``w r^2``, without the 1/2
of rho's quadratic limit; we keep it so that every step lowers J: the IRLS step
minimises a majoriser of rho.) Iterations stop when J changes by less than ``tol`` of
its value, or after ``max_iterations``. Missing entries (alpha = 0) follow the bases
alone (§3.5). With ``robust`` False rho is the plain quadratic r^2 / 2 (w = alpha): the
least-squares version of the filter.

Speed: step (i) and the overlap-add are one linear map z -> a. Away from the clip's
ends it is a multichannel FIR filter, a_t = sum_d G_d z_{t+d} with L x L taps G_d
(d = 1 - M .. M - 1) summed from the diagonal blocks of E E^T, applied by FFT in
overlapping blocks of frames (overlap-save): per frequency one L x L product instead of
2 M - 1 of them per frame; the 2 (M - 1) windows that would stick out of the clip are
subtracted explicitly, so the result is the window-by-window computation up to float32
rounding. The solver keeps its (F, L) arrays channel-major (Fortran order): the FFT and
the banded solves of its preconditioner then run along contiguous frames.

With the smoothness term the conjugate gradients are preconditioned by a symmetric
two-level cycle, a coarse grid of piecewise-linear motion inside (:func:`_cg_filter`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
from numpy.lib.stride_tricks import sliding_window_view
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.ndimage import correlate1d, median_filter

from workbench.engine.smoothing import second_difference_band

#: IRLS re-weightings per motion update (each lowers J; the outer loop continues anyway)
IRLS_STEPS = 3
#: frames per FFT of the filter (overlap-save; at least 8 M): each block gives
#: FFT_FRAMES - 2 (M - 1) frames, 85 % of 256 at M = 20. The 10-minute take's 72,000 x 70
#: channels are filtered in 0.09-0.10 s, against 0.30 s as one direct product per frame
#: (2-core Xeon with AMX)
FFT_FRAMES = 256
#: blocks per batch of the FFT and the per-frequency products (keeps them near the cache)
FFT_BATCH = 16


def coverage(n_frames: int, window: int) -> np.ndarray:
    """(F,) number of windows that cover each frame."""
    return np.convolve(np.ones(n_frames - window + 1), np.ones(window))


class WindowProjector:
    """z (F, L) -> (a (F, L), prior energy): a_t sums the reconstructions E E^T z_s of
    frame t over the windows s covering it; the prior energy is sum_s ||z_s - E E^T
    z_s||^2. ``bases`` (L M, K) has orthonormal columns, entries ordered l M + m."""

    def __init__(self, bases: np.ndarray, window: int) -> None:
        M = self.window = window
        E = np.asarray(bases, float)
        L = E.shape[0] // M
        P = (E @ E.T).reshape(L, M, L, M).transpose(1, 0, 3, 2)  # [m, l, m', l']
        taps = np.zeros((2 * M - 1, L, L))  # [d + M - 1, l', l] = G_d[l, l']
        for d in range(1 - M, M):
            for m in range(max(0, -d), min(M, M - d)):
                taps[d + M - 1] += P[m, :, m + d, :].T
        self.taps = taps  # (2 M - 1, L, L): a_t = sum_j z_{t + j - M + 1} @ taps[j]
        # their correlation as one product per frequency: the taps' conjugate DFT over
        # fft_frames, (fft_frames / 2 + 1, L, L)
        self.fft_frames = max(FFT_FRAMES, 8 * M)
        self.response = np.conj(scipy.fft.rfft(taps, n=self.fft_frames, axis=0)).astype(np.complex64)
        # the windows sticking out of the clip by k = 1 .. M - 1 frames at either end,
        # as maps from the first (last) M - 1 frames to their reconstructions there
        head = np.zeros((M - 1, L, M - 1, L))
        tail = np.zeros((M - 1, L, M - 1, L))
        for k in range(1, M):
            n = M - k  # frames of the window inside the clip
            head[:n, :, :n, :] += P[k:, :, k:, :]
            tail[M - 1 - n :, :, M - 1 - n :, :] += P[:n, :, :n, :]
        # float32 like the taps: at 70 channels each map is (19 x 70)^2 entries, read whole
        # on every application (14 MB in float64; half the projector's time besides the
        # taps' product on these CPUs)
        self.head = head.reshape((M - 1) * L, (M - 1) * L).astype(np.float32)
        self.tail = tail.reshape((M - 1) * L, (M - 1) * L).astype(np.float32)

    def __call__(self, z: np.ndarray) -> tuple[np.ndarray, float]:
        """a (F, L) of z (F, L) (:meth:`added`) and the prior energy."""
        added = self.added(z)
        prior = float(np.sum(coverage(len(z), self.window)[:, None] * np.square(z)) - np.sum(z * added))
        return added, max(prior, 0.0)

    def added(self, z: np.ndarray) -> np.ndarray:
        """a (F, L) of z (F, L): each frame's reconstructions summed over its windows.
        Channel-major (Fortran-order) z is read without a copy of its layout, and a is
        returned channel-major."""
        M = self.window
        F, L = z.shape
        N = self.fft_frames
        B = N - 2 * (M - 1)  # frames each block gives
        n_blocks = -(-F // B)
        padded = np.zeros((L, n_blocks * B + 2 * (M - 1)), np.float32)
        padded[:, M - 1 : M - 1 + F] = z.T
        blocks = sliding_window_view(padded, N, axis=1)[:, ::B]  # (L, n_blocks, N), no copy
        added = np.empty((L, F))
        for b0 in range(0, n_blocks, FFT_BATCH):
            spectra = scipy.fft.rfft(blocks[:, b0 : b0 + FFT_BATCH], axis=-1)  # (L, n, K)
            products = np.matmul(spectra.transpose(2, 1, 0), self.response)  # (K, n, L)
            frames = scipy.fft.irfft(products, n=N, axis=0)[:B]  # (B, n, L): the valid frames
            start, stop = b0 * B, min(F, (b0 + frames.shape[1]) * B)
            added[:, start:stop] = frames.transpose(2, 1, 0).reshape(L, -1)[:, : stop - start]
        added = added.T
        added[: M - 1] -= (self.head @ z[: M - 1].astype(np.float32).ravel()).reshape(M - 1, L)
        added[F - M + 1 :] -= (self.tail @ z[F - M + 1 :].astype(np.float32).ravel()).reshape(M - 1, L)
        return added


class CoarseGrid:
    """Piecewise-linear motion over ``n_frames`` frames, held at nodes every ``spacing``
    frames (node i at frame i * spacing; ``n_nodes`` = ceil(F / spacing) + 1, the last
    beyond the clip): the coarse space of :func:`robust_filter`'s two-level preconditioner.
    ``prolong`` maps node values (L, n_nodes) to frames (F, L), channel-major; ``restrict``
    is its transpose; :meth:`galerkin_band` gives the Galerkin product P^T X P of an
    operator X on the frames as a lower band ``(u + 1, L, n_nodes)`` (entry [k, l, i] the
    coupling of nodes i + k and i of channel l; 0 past the last node), for
    ``cholesky_banded``. A 10-minute take's band is 25 MB, so Toeplitz operators are held
    as their couplings (:meth:`toeplitz_coupling`) until then."""

    def __init__(self, n_frames: int, spacing: int) -> None:
        self.n_frames, self.spacing = n_frames, spacing
        self.n_nodes = -(-n_frames // spacing) + 1
        self.next_share = np.arange(spacing) / spacing  # frame i * spacing + s: the next node's share
        self.own_share = 1.0 - self.next_share

    def restrict(self, v: np.ndarray) -> np.ndarray:
        """P^T v: (L, n_nodes) of v (F, L). Frame i * spacing + s counts towards node i by
        ``own_share[s]`` and node i + 1 by ``next_share[s]``; summed over each s's frames in
        turn, so no (F, L) temporary is made (a 10-minute take's are 40 MB)."""
        frames = v.T  # (L, F): contiguous rows for channel-major v
        nodes = np.zeros((v.shape[1], self.n_nodes))
        for s in range(min(self.spacing, self.n_frames)):
            at = frames[:, s :: self.spacing]
            m = at.shape[1]
            nodes[:, :m] += self.own_share[s] * at
            nodes[:, 1 : m + 1] += self.next_share[s] * at
        return nodes

    def prolong(self, nodes: np.ndarray) -> np.ndarray:
        """P x: (F, L), channel-major, of node values x (L, n_nodes)."""
        frames = np.empty((nodes.shape[0], self.n_frames))
        for s in range(min(self.spacing, self.n_frames)):
            m = frames[:, s :: self.spacing].shape[1]
            frames[:, s :: self.spacing] = self.own_share[s] * nodes[:, :m] + self.next_share[s] * nodes[:, 1 : m + 1]
        return frames.T

    def toeplitz_coupling(self, taps: np.ndarray) -> np.ndarray:
        """(u + 1, L): entry [k, l] the coupling of nodes i and i + k in P^T T P, T the
        symmetric Toeplitz operator of ``taps`` (2 D + 1, L) on channel l, (T v)_t = sum_o
        taps[o + D] v_{t+o}, extended past the clip's ends (so positive semi-definite
        where the taps' symbol is): sum_o taps(o) R(o - k spacing), R the autocorrelation
        of a node's hat."""
        r, D = self.spacing, (len(taps) - 1) // 2
        hat = 1.0 - np.abs(np.arange(1 - r, r)) / r
        R = np.correlate(hat, hat, "full")  # lags -(2 r - 2) .. 2 r - 2
        u = (D + 2 * r - 2) // r
        lags = np.arange(-D, D + 1)[None, :] - r * np.arange(u + 1)[:, None] + 2 * r - 2  # index into R
        inside = (lags >= 0) & (lags < len(R))
        return np.where(inside, R[np.clip(lags, 0, len(R) - 1)], 0.0) @ taps

    def galerkin_band(self, coupling: np.ndarray, w: np.ndarray) -> np.ndarray:
        """P^T (diag(w) + T) P as a lower band (u + 1, L, n_nodes), u >= 1: w (F, L) per-
        frame weights, T the Toeplitz operators of :meth:`toeplitz_coupling`'s ``coupling``."""
        band = np.zeros((max(len(coupling), 2), w.shape[1], self.n_nodes))
        band[: len(coupling)] = coupling[:, :, None]
        weights = w.T
        for s in range(min(self.spacing, self.n_frames)):
            at = weights[:, s :: self.spacing]
            m = at.shape[1]
            band[0, :, :m] += self.own_share[s] ** 2 * at
            band[0, :, 1 : m + 1] += self.next_share[s] ** 2 * at
            band[1, :, :m] += self.own_share[s] * self.next_share[s] * at
        for k in range(1, len(band)):
            band[k, :, self.n_nodes - k :] = 0.0
        return band


@dataclass(frozen=True)
class FilterResult:
    """z: filtered channels (F, L); reconstruction: the mean over the covering windows
    of their basis reconstructions E c_s (F, L); weight: final data weights alpha * w
    (F, L), 1 for a sample taken at face value, near 0 for an outlier, 0 where missing;
    cost: J after each coefficient update; iterations: motion updates made."""

    z: np.ndarray
    reconstruction: np.ndarray
    weight: np.ndarray  # exp(-r^2 / p^2) where observed (1 without ``robust``), 0 where missing
    cost: list[float]
    iterations: int


def robust_filter(
    y: np.ndarray,
    observed: np.ndarray,
    projector: WindowProjector,
    prior_weight: float,
    welsch_p: "float | np.ndarray",
    robust: bool = True,
    tol: float = 1e-3,
    max_iterations: int = 100,
    method: str = "alternating",
    smoothness: "np.ndarray | None" = None,
    refit_weight: float = 0.0,
    start_median_frames: int = 1,
) -> FilterResult:
    """Minimise J for ``y`` (F, L), finite everywhere (missing entries initialised, e.g.
    by linear interpolation), with ``observed`` (F, L): bools, or non-negative data
    weights alpha (0 where missing; a larger alpha trusts the sample more, e.g. the
    inverse of its estimated noise variance). ``welsch_p`` is a scalar or an array
    broadcasting to (F, L) (e.g. one scale per channel). Clips shorter than the window
    are padded at the end with their last frame, marked missing, and cropped again.

    ``method`` "alternating": the paper's coefficient / motion updates (each motion
    update ``IRLS_STEPS`` element-wise IRLS steps); "cg": every iteration fixes the IRLS
    weights w and minimises the resulting quadratic majoriser of J exactly over z (the
    coefficients c_s = E^T z_s are eliminated in closed form), i.e. solves
    ``(W + 2 lambda (N - A)) z = W y`` by preconditioned conjugate gradients (to a
    relative residual of ``CG_TOL``, at most ``CG_STEPS`` steps; the preconditioner:
    :func:`_cg_filter`); the same
    objective, reached in far fewer filter applications when lambda n >> w (the
    alternating updates then crawl). ``smoothness`` mu (L,) adds the second-difference
    term of J (needs "cg"). ``refit_weight`` > 0 ("cg" only): once the iterations stop,
    z is solved for once more with the final IRLS weights fixed and the bases term
    weighted ``refit_weight`` instead of ``prior_weight`` (``cost`` stays J's). With
    ``robust``, the iterations start from ``y`` filtered by a running median over
    ``start_median_frames`` frames (1: from ``y`` itself)."""
    F, M = y.shape[0], projector.window
    if F < M:
        y = np.pad(y, ((0, M - F), (0, 0)), mode="edge")
        observed = np.pad(observed, ((0, M - F), (0, 0)), constant_values=False)
    if (smoothness is not None or refit_weight > 0) and method != "cg":
        raise ValueError('the smoothness term and the refit need method="cg"')
    alpha = np.asfortranarray(observed, float)  # channel-major, as every (F, L) array below
    y = np.asfortranarray(y, float)
    lam = float(prior_weight)
    p2 = np.square(np.asarray(welsch_p, float))
    n = coverage(y.shape[0], M)[:, None]

    def weights(z: np.ndarray) -> np.ndarray:
        return alpha * np.exp(-np.square(z - y) / p2) if robust else alpha

    def data_cost(z: np.ndarray) -> float:
        r2 = np.square(z - y)
        rho = p2 / 2.0 * -np.expm1(-r2 / p2) if robust else r2 / 2.0
        return float(np.sum(alpha * rho))

    z = np.array(y, dtype=float, order="F")
    if robust and start_median_frames > 1:  # the Welsch objective is not convex: start robustly
        z = np.asfortranarray(median_filter(z, size=(start_median_frames, 1), mode="nearest"))
    costs: list[float] = []
    iterations = 0
    if method == "cg":
        mu = np.zeros(y.shape[1]) if smoothness is None else np.asarray(smoothness, float)

        def cost(z: np.ndarray) -> float:  # data and smoothness terms
            return data_cost(z) + float(np.sum(mu * np.square(np.diff(z, n=2, axis=0))))

        return _cg_filter(
            y, alpha, z, projector, lam, mu, n, weights, cost, tol, max_iterations, F, p2, robust, refit_weight
        )
    while True:
        added, prior = projector(z)
        costs.append(data_cost(z) + lam * prior)
        if len(costs) > 1 and abs(costs[-2] - costs[-1]) <= tol * costs[-2]:
            break
        if iterations == max_iterations:
            break
        for _ in range(IRLS_STEPS):
            w = weights(z)
            z = (w * y + 2.0 * lam * added) / (w + 2.0 * lam * n)
        iterations += 1
    trust = (alpha > 0) * (np.exp(-np.square(z - y) / p2) if robust else 1.0)
    return FilterResult(z[:F], (added / n)[:F], trust[:F], costs, iterations)


#: conjugate-gradient iterations per quadratic solve, and their relative residual target
#: (1e-3 with the two-level preconditioner: as near the minimum as 3e-4 got with the
#: banded one alone, which seldom reached it; 3e-4 and 3e-3 scored worse on validation,
#: ``docs/engines/mssa.md``, *Speed*)
CG_STEPS = 80
CG_TOL = 1e-3
#: frames per node of the two-level preconditioner's coarse grid (:class:`CoarseGrid`)
COARSE_FRAMES = 8


def _inner(a: np.ndarray, b: np.ndarray) -> float:
    """sum(a * b) of two (F, L) arrays, without the product array: one BLAS dot product
    over channel-major (Fortran-order) arrays' memory as it lies (others are copied)."""
    return float(np.dot(a.T.reshape(-1), b.T.reshape(-1)))


def second_difference_gram(v: np.ndarray) -> np.ndarray:
    """D2^T D2 v for v (F, L), F >= 2, D2 the second difference over frames (F - 2, F); in
    v's memory order. One pass of the interior's filter (1, -4, 6, -4, 1), then the two
    rows at either end, where fewer differences reach (also right where they overlap, F < 4)."""
    out = correlate1d(v, [1.0, -4.0, 6.0, -4.0, 1.0], axis=0, output=np.empty_like(v), mode="constant")
    out[0] -= 5.0 * v[0] - 2.0 * v[1]
    out[1] += 2.0 * v[0] - v[1]
    out[-1] -= 5.0 * v[-1] - 2.0 * v[-2]
    out[-2] += 2.0 * v[-1] - v[-2]
    return out


def _cg_filter(
    y, alpha, z, projector, lam, mu, n, weights, data_cost, tol, max_iterations, F, p2, robust, refit_weight
):
    """``robust_filter`` with ``method="cg"`` (see there); ``data_cost`` includes the
    smoothness term of weights ``mu`` (L,).

    With the smoothness term each solve is preconditioned by one symmetric two-level
    cycle: B, a banded Cholesky solve of every channel (the data and smoothness terms
    exact, the bases term by its diagonal), then a correction on a coarse grid of
    piecewise-linear motion (:class:`CoarseGrid`, nodes every ``COARSE_FRAMES`` frames;
    there the Galerkin product of the data and smoothness terms and of each channel's own
    bases term), then B again. The bases term is a high-pass on each channel (near 0 for
    periods above some 16 frames, 2 lambda n for short ones), so B alone charges the
    smooth motion the bases keep some 30 times the data weight, and CG crawled on it,
    stopping at ``CG_STEPS`` short of the tolerance; the coarse grid holds that motion. A
    step costs three filter applications instead of one and converges in far fewer (the
    10-minute take's first 12,000 frames: 41 steps instead of 222, ``docs/engines/mssa.md``,
    *A coarse grid in the preconditioner*). Without the smoothness term: B's diagonal."""
    M = projector.window
    g0 = np.diag(projector.taps[M - 1]) / M  # diagonal of A / n
    costs: list[float] = []
    iterations = 0
    costs.append(data_cost(z) + lam * projector(z)[1])
    smoothed = mu.any()  # the smoothness term: a two-level preconditioner
    if smoothed:
        grid = CoarseGrid(len(y), COARSE_FRAMES)
        bases_taps = -np.diagonal(projector.taps, axis1=1, axis2=2)  # each channel's own n - a, (2 M - 1, L)
        bases_taps[M - 1] += M
        bases = grid.toeplitz_coupling(bases_taps)
        smooth = grid.toeplitz_coupling(np.outer([1.0, -4.0, 6.0, -4.0, 1.0], 2.0 * mu))
        bases_coupling, smooth_coupling = (  # one height: the bands differ with the window
            np.pad(c, ((0, max(len(bases), len(smooth)) - len(c)), (0, 0))) for c in (bases, smooth)
        )
    # the bases term's share of the diagonal; the cycle's smoother B needs 2 B - A positive
    # definite, so there at least half (channels the bases hold almost whole have g0 near 1)
    share = np.maximum(1.0 - g0, 0.5) if smoothed else 1.0 - g0

    # The (F, L) arrays below (40 MB each on a 10-minute take) are channel-major and
    # updated in place where they can be.
    def solve(z, w, lam):
        """Minimise the quadratic with data weights ``w`` and bases weight ``lam``: PCG
        from ``z`` to a relative residual of ``CG_TOL`` (at most ``CG_STEPS`` steps)."""
        diagonal = w + 2.0 * lam * n * share + 1e-12
        data_and_coverage = w + 2.0 * lam * n

        def apply(v):  # w v + 2 lam (n v - a(v)) + 2 mu D2'D2 v
            out = data_and_coverage * v
            reconstructed = projector.added(v)
            reconstructed *= 2.0 * lam
            out -= reconstructed
            del reconstructed
            smooth = second_difference_gram(v)
            smooth *= 2.0 * mu
            out += smooth
            return out

        if not smoothed:

            def precond(v):
                return v / diagonal
        else:
            # B: exact for the data and smoothness terms, the bases term by its diagonal
            # (banded Cholesky of every channel); it overcharges the smooth motion the bases
            # keep, which the coarse grid's C = P^T (W + 2 lam T + 2 mu D2'D2) P holds, T
            # each channel's own bases term. One symmetric two-level cycle: B, C, B.
            ab = second_difference_band(len(y))[:, None, :] * (2.0 * mu)[None, :, None]  # (3, L, F)
            ab[0] += diagonal.T
            factor = cholesky_banded(ab.reshape(3, -1), overwrite_ab=True, lower=True, check_finite=False)
            del ab
            coarse = grid.galerkin_band(2.0 * lam * bases_coupling + smooth_coupling, w)
            coarse_factor = cholesky_banded(
                coarse.reshape(len(coarse), -1), overwrite_ab=True, lower=True, check_finite=False
            )
            del coarse

            def fine(v, overwrite=False):  # overwrite: the solution in v's memory
                x = cho_solve_banded((factor, True), v.T.reshape(-1), overwrite_b=overwrite, check_finite=False)
                return x.reshape(v.shape[1], v.shape[0]).T

            def precond(v):  # the residual left after each stage in place: 40 MB a copy
                x = fine(v)
                left = apply(x)
                np.subtract(v, left, out=left)
                nodes = cho_solve_banded((coarse_factor, True), grid.restrict(left).reshape(-1), check_finite=False)
                del left
                x += grid.prolong(nodes.reshape(v.shape[1], -1))
                left = apply(x)
                np.subtract(v, left, out=left)
                x += fine(left, overwrite=True)
                return x

        z = z.copy(order="F")
        r = w * y - apply(z)
        d = precond(r)
        rz = _inner(r, d)
        target = CG_TOL**2 * float(np.sum(np.square(w * y))) + 1e-30
        for _ in range(CG_STEPS):
            if _inner(r, r) <= target:
                break
            q = apply(d)
            step = rz / _inner(d, q)
            z += step * d
            q *= step
            r -= q
            del q
            s_ = precond(r)
            rz, rz_old = _inner(r, s_), rz
            d *= rz / rz_old
            d += s_
            del s_
        return z

    while iterations < max_iterations:
        z = solve(z, weights(z), lam)
        iterations += 1
        costs.append(data_cost(z) + lam * projector(z)[1])
        if not robust or abs(costs[-2] - costs[-1]) <= tol * costs[-2]:
            break
    if refit_weight > 0:
        z = solve(z, weights(z), refit_weight)
    added = projector.added(z)  # once, at the end: not held through the solves
    trust = (alpha > 0) * (np.exp(-np.square(z - y) / p2) if robust else 1.0)
    return FilterResult(z[:F], (added / n)[:F], trust[:F], costs, iterations)
