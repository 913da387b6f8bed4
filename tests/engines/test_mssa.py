"""The ``mssa`` engine (Lou and Chai 2010): bases, robust filtering, gap filling, the
position mode, skeleton checks and saved state. Bases are fitted here on four short
CMU training takes; the walk fixture (02_01) is not among them."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from engines.mssa import MSSA
from engines.mssa.bases import window_blocks
from engines.mssa.solver import CG_TOL, CoarseGrid, WindowProjector, coverage, robust_filter, second_difference_gram
from workbench import registry
from workbench.core import Observation
from workbench.core.motion import angle_columns, channel_mask, joint_angle_columns
from workbench.core.rotations import wrap_deg
from workbench.corruption import parse_corruption
from workbench.data import select
from workbench.engine import EngineError, NotFittedError
from workbench.engine.base import HUMANOID_SIGNATURE
from workbench.metrics import angle_error_deg, bone_lengths
from workbench.testing import check_engine

FIT_CLIPS = ("cmu/walk/02_02", "cmu/walk/07_01", "cmu/jog/02_03", "cmu/run/09_01")


@pytest.fixture(scope="module")
def fitted(clips):
    by_id = {c.id: c for c in clips}
    return MSSA().fit([by_id[i].load() for i in FIT_CLIPS])


def with_params(engine: MSSA, **changes) -> MSSA:
    """Another engine sharing ``engine``'s fitted bases."""
    other = MSSA(dataclasses.replace(engine.params, **changes))
    other.models_, other.skeleton_signature_, other.fps_ = engine.models_, engine.skeleton_signature_, engine.fps_
    return other


def modelled_angle_columns(engine: MSSA, motion) -> np.ndarray:
    return np.intersect1d(engine.models_["angles"].columns, angle_columns(motion.skeleton))


@pytest.mark.parametrize("space", ["angles", "positions"])
def test_conformance(fitted, walk, kick, space):
    check_engine(lambda: with_params(fitted, space=space), walk.slice(0, 150), kick.slice(0, 150))


def test_bases_are_orthonormal_and_keep_the_requested_energy(fitted):
    kept = fitted.params.energy_kept
    for space, model in fitted.models_.items():
        E = model.bases.astype(float)
        LM, K = E.shape
        assert LM == 20 * model.columns.size and 0 < K < LM, space
        assert np.allclose(E.T @ E, np.eye(K), atol=1e-5), space
        assert np.all(np.diff(model.spectrum) <= 1e-9 * model.spectrum[0]), space
        assert model.energy_share >= kept - 1e-12, space
        assert model.spectrum[: K - 1].sum() / model.spectrum.sum() < kept, f"{space}: K is not the smallest"
    # constant channels (CMU's LHipJoint rotations are always 0) are held, not modelled
    assert not np.isin([6, 7, 8], fitted.models_["angles"].columns).any()
    assert np.isin([6, 7, 8], fitted.models_["angles"].held).all()


def test_projector_matches_the_window_by_window_projection(fitted):
    model = fitted.models_["angles"]
    E, M = model.bases.astype(float), 20
    rng = np.random.default_rng(0)
    for F in (20, 33, 90, 219, 4000):  # 219: two FFT blocks; 4000: two batches of them (FFT_BATCH)
        z = np.cumsum(rng.normal(size=(F, model.columns.size)), axis=0) * 0.2
        added, prior = WindowProjector(E, M)(z)
        ref, ref_prior = np.zeros_like(z), 0.0
        for s0, W in window_blocks(z, M):
            R = (W @ E) @ E.T
            ref_prior += np.sum((W - R) ** 2)
            R = R.reshape(len(W), -1, M)
            for s in range(len(W)):
                ref[s0 + s : s0 + s + M] += R[s].T
        assert np.allclose(added, ref, atol=1e-5 * np.abs(ref).max()), F
        assert np.isclose(prior, ref_prior, rtol=1e-4), F
        channel_major = WindowProjector(E, M).added(np.asfortranarray(z))  # the solver's layout
        assert channel_major.flags.f_contiguous and np.array_equal(channel_major, added), F


def _outlier_case(motion, engine, rate=0.05, seed=1):
    """``motion`` with mild noise on the modelled angle channels and 5 % of those entries
    off by 60-120 degrees; returns (observation, outlier mask (F, D), columns)."""
    rng = np.random.default_rng(seed)
    X = motion.channels
    cols = modelled_angle_columns(engine, motion)
    X[:, cols] += rng.normal(size=(motion.n_frames, cols.size)) * 1.0
    hit = np.zeros(X.shape, bool)
    hit[:, cols] = rng.random((motion.n_frames, cols.size)) < rate
    X[hit] += rng.choice([-1.0, 1.0], hit.sum()) * rng.uniform(60.0, 120.0, hit.sum())
    return Observation(motion.with_channels(X)), hit, cols


def test_outliers_are_rejected_better_than_by_least_squares(fitted, walk):
    obs, hit, cols = _outlier_case(walk, fitted)
    robust = fitted.clean(obs)
    plain = with_params(fitted, robust=False).clean(obs)

    def rms(res):
        err = angle_error_deg(walk, res.motion)
        keep = np.isin(angle_columns(walk.skeleton), cols)
        return float(np.sqrt(np.mean(err[:, keep] ** 2)))

    d = wrap_deg((obs.motion.channels - walk.channels)[:, cols])
    noisy = float(np.sqrt(np.mean(d**2)))
    assert rms(robust) < 0.35 * rms(plain) and rms(plain) < noisy
    assert rms(robust) < 3.0
    # the paper's own solver and objective (no smoothness term, refit or median start)
    # rejects outliers too, less well (its alternating updates crawl at lambda 3)
    paper = with_params(
        fitted, solver="alternating", smoothness=0.0, refit_prior_weight=0.0, start_median_frames=1
    ).clean(obs)
    assert rms(robust) < 0.5 * rms(paper) and rms(paper) < rms(plain)
    w = robust.diagnostics["robust_weight"]
    assert w.shape == walk.channels.shape
    assert np.median(w[hit]) < 0.05 and np.mean(w[hit] < 0.5) > 0.9
    assert np.median(w[:, cols][~hit[:, cols]]) > 0.9
    assert np.all(w[:, :6] == 1.0)  # the root is not in the robust filter: its smoother
    assert np.abs(robust.motion.channels[:, :6] - walk.channels[:, :6]).max() < 1.0  # passes it ~clean


def test_objective_never_increases(fitted, walk):
    obs, _, cols = _outlier_case(walk, fitted)
    model = fitted.models_["angles"]
    X = obs.motion.channels[:, model.columns]
    u = (X - np.median(X, axis=0)) / model.scale
    res = robust_filter(u, np.ones_like(u, bool), model.projector, 0.1, 3.0, tol=0.0, max_iterations=15)
    assert res.iterations == 15
    assert np.all(np.diff(res.cost) <= 1e-9 * res.cost[0])
    # the conjugate-gradient solver minimises the same objective, with per-channel data
    # weights and scales, and never raises it either; it gets lower than 15 alternating rounds
    alpha = np.ones_like(u) / np.linspace(0.5, 2.0, u.shape[1])
    cg = robust_filter(u, alpha, model.projector, 0.1, 3.0, tol=0.0, max_iterations=6, method="cg")
    assert cg.iterations == 6
    assert np.all(np.diff(cg.cost) <= 1e-6 * cg.cost[0])
    same = robust_filter(u, np.ones_like(u, bool), model.projector, 0.1, 3.0, tol=0.0, max_iterations=6, method="cg")
    assert same.cost[-1] <= res.cost[-1]
    smooth = robust_filter(
        u, alpha, model.projector, 0.1, 3.0, tol=0.0, max_iterations=6, method="cg", smoothness=np.full(u.shape[1], 5.0)
    )
    assert np.all(np.diff(smooth.cost) <= 1e-6 * smooth.cost[0])


def test_smoothness_term_is_the_kalman_smoothers_prior(fitted, walk):
    # without the bases term, least squares plus the smoothness term is the constant-
    # velocity RTS smoother of engines.kalman with q = r / lambda
    from workbench.engine.smoothing import cv_smooth

    model = fitted.models_["angles"]
    X = walk.channels[:200, model.columns]
    u = (X - np.median(X, axis=0)) / model.scale + np.random.default_rng(5).normal(0.0, 0.2, (200, model.columns.size))
    seen = np.ones_like(u, bool)
    seen[60:90] = False  # a gap: both bridge it with the same cubic-spline-like fill
    ratio = np.geomspace(10.0, 1e4, u.shape[1])
    res = robust_filter(u, seen, model.projector, 0.0, 3.0, robust=False, method="cg", smoothness=ratio / 2)
    kalman = cv_smooth(u, seen, 1.0 / ratio, np.ones(u.shape[1]))
    assert np.max(np.abs(res.z - kalman)) < 0.02 * np.max(np.abs(kalman))
    with pytest.raises(ValueError, match="cg"):
        robust_filter(u, seen, model.projector, 0.1, 3.0, smoothness=ratio / 2)
    with pytest.raises(ValueError, match="cg"):
        with_params(fitted, solver="alternating")


def test_engine_smoothness_uses_the_noise_kalman_would_find(fitted, walk):
    # the engine picks each channel's smoothing ratio from the noise it measures, not
    # from the noise plus the model-error floor of the data weights: with the bases term
    # and the robust weights off it is the kalman engine (at light noise the floor's
    # inflated variance put it 7 times further from it than here)
    cols = modelled_angle_columns(fitted, walk)
    X = walk.channels
    X[:, cols] += np.random.default_rng(2).normal(size=(walk.n_frames, cols.size)) * 0.3
    obs = Observation(walk.with_channels(X))
    smoother = with_params(fitted, prior_weight=1e-9, robust=False, refit_prior_weight=0.0).clean(obs)
    kalman = registry.create("kalman").clean(obs)
    gap = np.sqrt(np.mean(np.square(smoother.motion.channels[:, cols] - kalman.motion.channels[:, cols])))
    kalman_error = np.sqrt(np.mean(np.square(kalman.motion.channels[:, cols] - walk.channels[:, cols])))
    assert gap < 0.15 * kalman_error, (gap, kalman_error)


def test_missing_entries_are_filled_and_observed_ones_kept_close(fitted, walk):
    rng = np.random.default_rng(2)
    F, J = walk.n_frames, walk.skeleton.n_joints
    observed = rng.random((F, J)) > 0.05
    observed[100:130, [3, 8, 19]] = False  # LeftLeg, RightLeg, LeftForeArm for 1/4 s
    observed[:, 0] = True
    res = fitted.clean(Observation(walk, observed))
    out = res.motion.channels
    assert np.isfinite(out).all() and out.shape == walk.channels.shape
    mask = channel_mask(observed, walk.skeleton)
    err = np.abs(wrap_deg(out - walk.channels))
    cols = modelled_angle_columns(fitted, walk)
    # four training takes: observed samples stay within ~2 degrees, filled ones ~3 (RMS)
    assert np.sqrt(np.mean(err[:, cols][mask[:, cols]] ** 2)) < 2.5
    assert np.sqrt(np.mean(err[:, cols][~mask[:, cols]] ** 2)) < 5.0
    assert np.all(res.diagnostics["robust_weight"][~mask] == 0.0)


def test_position_mode_returns_a_motion_with_the_skeletons_bone_lengths(fitted, walk):
    engine = with_params(fitted, space="positions")
    assert engine.info.space == "positions" and engine.spec == "mssa:space=positions"
    obs, _, _ = _outlier_case(walk, fitted)
    observed = np.ones((walk.n_frames, walk.skeleton.n_joints), bool)
    observed[50:70, 19] = False
    res = engine.clean(Observation(obs.motion, observed))
    motion = res.motion
    assert motion.n_frames == walk.n_frames and np.isfinite(motion.channels).all()
    rest = np.linalg.norm(walk.skeleton.offsets[1:], axis=1)
    assert np.allclose(bone_lengths(motion.positions, walk.skeleton.parents), rest[None], atol=1e-6)
    assert res.diagnostics["robust_weight"].shape == (walk.n_frames, 3 * walk.skeleton.n_joints)
    noisy = obs.motion.positions - obs.motion.positions[:, :1]
    clean = motion.positions - motion.positions[:, :1]
    truth = walk.positions - walk.positions[:, :1]

    def err(P):
        return np.mean(np.linalg.norm(P - truth, axis=2))

    assert err(clean) < 0.5 * err(noisy)


def test_position_mode_keeps_short_levers_at_their_smoothed_observed_angles(fitted, walk):
    # the hands and finger bases are not aimed from filtered positions a few mm off: they
    # keep their observed angles through the kalman smoother, as in cae
    from workbench.core.kinematics import short_lever_joints
    from workbench.engine.smoothing import smooth_observed

    obs, _, _ = _outlier_case(walk, fitted, rate=0.0)
    short = short_lever_joints(walk.skeleton, 5.0)
    cols = joint_angle_columns(short)
    kept = with_params(fitted, space="positions").clean(obs).motion.channels[:, cols]
    everywhere = np.ones((walk.n_frames, cols.size), bool)
    np.testing.assert_allclose(kept, smooth_observed(obs.motion.channels[:, cols], everywhere), atol=1e-6)
    aimed = with_params(fitted, space="positions", short_lever_cm=0.0, angle_lever_cm=0.0).clean(obs).motion

    def rms(channels):
        return float(np.sqrt(np.mean(np.square(channels - walk.channels[:, cols]))))

    assert rms(kept) < 0.7 * rms(aimed.channels[:, cols])


def test_position_mode_keeps_the_feet_at_their_smoothed_angles_under_angle_noise(fitted, walk):
    # as in cae: aimed at a toe whose position carries the whole leg's noise, a foot
    # turns far more than its own smoothed angles do (workbench.engine.smoothing.ik_reference)
    feet = [walk.skeleton.index(n) for n in ("LeftFoot", "RightFoot")]
    obs = parse_corruption("angular:0.5").apply(walk, seed=0)

    def feet_error(**params):
        out = with_params(fitted, space="positions", **params).clean(obs).motion
        return np.sqrt(np.mean((out.angles_deg[:, feet] - walk.angles_deg[:, feet]) ** 2))

    assert feet_error() < 0.5 * feet_error(angle_lever_cm=0.0)


def test_refuses_another_skeleton_and_mixed_training(fitted, walk, kick):
    with pytest.raises(EngineError, match="skeleton"):
        fitted.clean(Observation(kick))
    with pytest.raises(EngineError, match="skeleton"):
        MSSA().fit([walk, kick])


def test_clean_before_fit_raises_not_fitted(walk):
    with pytest.raises(NotFittedError):
        MSSA().clean(Observation(walk))
    with pytest.raises(NotFittedError):
        registry.create("mssa:window_frames=10").clean(Observation(walk))  # no bases for M=10


@pytest.mark.slow
def test_save_load_round_trip_gives_identical_output(fitted, walk, tmp_path):
    fitted.save(tmp_path, {"training": {"clips": list(FIT_CLIPS), "split": "train"}})
    loaded = MSSA().load(tmp_path)
    obs, _, _ = _outlier_case(walk, fitted)
    for space in ("angles", "positions"):
        a = with_params(fitted, space=space).clean(obs)
        b = with_params(loaded, space=space).clean(obs)
        assert np.array_equal(a.motion.channels, b.motion.channels), space
        assert np.array_equal(a.diagnostics["robust_weight"], b.diagnostics["robust_weight"]), space
    with pytest.raises(EngineError, match=r"trained with \{'window_frames': 20\}, not \{'window_frames': 10\}"):
        MSSA(MSSA.Params(window_frames=10)).load(tmp_path)


def test_committed_weights_load_and_were_fitted_on_the_train_split_only(clips):
    engine = registry.create("mssa")
    assert engine.skeleton_signature_ is not None, "engines/mssa/weights/ is missing"
    test_ids = {c.id for c in select(clips, "test")}
    assert test_ids
    for folder in engine.committed_weights().values():
        manifest = json.loads((folder / "manifest.json").read_text())
        assert manifest["training"]["split"] == "train"
        assert manifest["training"]["clips"] and not test_ids & set(manifest["training"]["clips"])
    assert all(m.energy_share >= engine.params.energy_kept - 1e-12 for m in engine.models_.values())


def test_position_noise_reaching_the_root_is_smoothed_in_angle_mode(held_out_walk):
    """Joint-position noise solved back to angles reaches the root; passed through, its
    noisy orientation would turn the whole cleaned body (worse than the input)."""
    from workbench.corruption import parse_corruption
    from workbench.metrics import mpjpe_cm

    take = held_out_walk.slice(0, 200)
    obs = parse_corruption("spatial:1").apply(take, seed=0)
    out = registry.create("mssa").clean(obs).motion
    assert mpjpe_cm(take, out) < 0.8 * mpjpe_cm(take, obs.motion)


@pytest.fixture(scope="module")
def universal(clips, studio_take):
    """Universal bases (the canonical humanoid's positions) from CMU and Bandai takes."""
    by_id = {c.id: c for c in clips}
    ids = FIT_CLIPS + ("cmu/jump/02_04", "cmu/other/02_05", "cmu/other/05_02")
    motions = [by_id[i].load() for i in ids] + [studio_take]
    return MSSA(MSSA.Params(space="positions", universal=True)).fit(motions)


def test_universal_bases_train_on_two_skeletons_and_clean_a_third(universal, kick, tmp_path):
    """Fitted on CMU and Bandai takes at 120 fps, they clean a Daz take (no toes: filled by
    the bases, dropped on the way back) on its own bones; the robust weights come back per
    take joint; saved and loaded, they give the same output."""
    assert universal.skeleton_signature_ == HUMANOID_SIGNATURE and universal.fps_ == 120.0
    assert set(universal.models_) == {"positions"} and universal.models_["positions"].columns.size <= 63
    take = kick.slice(0, 200)
    truth = universal.clean(Observation(take)).motion
    error = np.linalg.norm(truth.positions - take.positions, axis=2)  # cm: a clean take stays near
    assert np.median(error) < 0.5 and error.mean() < 2.0, (np.median(error), error.mean())  # few bases here
    obs = parse_corruption("angular:0.5+gaps:0.02").apply(take, seed=2)
    result = universal.clean(obs)
    assert np.isfinite(result.motion.channels).all()
    parents = take.skeleton.parents
    np.testing.assert_allclose(
        bone_lengths(result.motion.positions, parents), bone_lengths(take.positions, parents), atol=1e-6
    )
    assert result.diagnostics["robust_weight"].shape == (200, 3 * take.skeleton.n_joints)
    universal.save(tmp_path)
    again = MSSA(MSSA.Params(space="positions", universal=True)).load(tmp_path)
    np.testing.assert_array_equal(again.clean(obs).motion.channels, result.motion.channels)


def test_universal_bases_are_of_positions_and_need_every_canonical_joint(walk, kick):
    with pytest.raises(ValueError, match="space=positions,universal=true"):
        MSSA.Params(universal=True)
    with pytest.raises(EngineError, match="left_toes, right_toes"):
        MSSA(MSSA.Params(space="positions", universal=True)).fit([walk, kick])


def test_committed_universal_bases_clean_the_unseen_skeleton_in_position_space_only(kick):
    """``mssa:space=positions`` has no Daz bases of its own: it uses the committed universal
    ones, and says so; ``mssa`` (angles) has no universal form and refuses the take."""
    obs = parse_corruption("angular:0.5").apply(kick.slice(0, 120), seed=0)
    positions = registry.create("mssa:space=positions")
    assert np.isfinite(positions.clean(obs).motion.channels).all()
    assert positions.weights_used_.startswith("universal weights ") and "mssa-universal" in positions.weights_used_
    with pytest.raises(EngineError, match="no weights for this skeleton"):
        registry.create("mssa").clean(obs)


@pytest.mark.parametrize("frames", [2, 3, 4, 5, 50])
def test_second_difference_gram_is_d2_transposed_d2(frames):
    v = np.asfortranarray(np.random.default_rng(frames).normal(size=(frames, 3)))
    D2 = np.diff(np.eye(frames), 2, axis=0)  # (F - 2, F)
    got = second_difference_gram(v)
    np.testing.assert_allclose(got, D2.T @ D2 @ v, atol=1e-12)
    assert got.flags.f_contiguous  # the solver's channel-major layout is kept


@pytest.mark.parametrize("frames, spacing", [(50, 8), (57, 4), (9, 8), (100, 3)])
def test_coarse_grid_is_linear_interpolation_and_gives_galerkin_products(frames, spacing):
    rng = np.random.default_rng(frames)
    grid, L = CoarseGrid(frames, spacing), 3
    P = np.zeros((frames, grid.n_nodes))  # hats every spacing frames
    for t in range(frames):
        i, s = divmod(t, spacing)
        P[t, i], P[t, i + 1] = 1 - s / spacing, s / spacing
    v, nodes = rng.normal(size=(frames, L)), rng.normal(size=(L, grid.n_nodes))
    np.testing.assert_allclose(grid.restrict(v), (P.T @ v).T, atol=1e-12)
    np.testing.assert_allclose(grid.prolong(nodes), P @ nodes.T, atol=1e-12)
    assert grid.prolong(nodes).flags.f_contiguous  # the solver's channel-major layout

    def lower_band_of(C, band):
        for k, row in enumerate(band):
            np.testing.assert_allclose(row[: grid.n_nodes - k], np.diag(C, -k), atol=1e-12)
            assert not row[grid.n_nodes - k :].any()  # channels laid end to end do not couple
        assert np.allclose(C, np.triu(np.tril(C, len(band) - 1), 1 - len(band)))  # nothing outside the band

    w = rng.random((frames, L))
    D = 5  # a symmetric Toeplitz operator, extended past the clip's ends (the hats there too)
    taps = rng.normal(size=(2 * D + 1, L))
    taps += taps[::-1]
    E = 2 * spacing + D
    extended = np.zeros((frames + 2 * E, grid.n_nodes))
    for i in range(grid.n_nodes):
        for s in range(1 - spacing, spacing):
            extended[E + i * spacing + s, i] = 1 - abs(s) / spacing
    band = grid.galerkin_band(grid.toeplitz_coupling(taps), w)
    for channel in range(L):
        T = sum(np.diag(np.full(frames + 2 * E - abs(o), taps[o + D, channel]), o) for o in range(-D, D + 1))
        lower_band_of(extended.T @ T @ extended + P.T @ np.diag(w[:, channel]) @ P, band[:, channel])
    # the data weights alone: a tridiagonal band
    lower_band_of(P.T @ np.diag(w[:, 0]) @ P, grid.galerkin_band(np.zeros((1, L)), w)[:, 0])


def relative_residual(z, y, alpha, projector, lam, mu) -> float:
    """|W y - A z| / |W y| of the least-squares quadratic the "cg" solver minimises (data
    weights ``alpha``, bases weight ``lam``, smoothness ``mu``), written out from its terms."""
    n = coverage(len(y), projector.window)[:, None]
    A_z = alpha * z + 2.0 * lam * (n * z - projector.added(z)) + 2.0 * mu * second_difference_gram(z)
    return float(np.linalg.norm(alpha * y - A_z) / np.linalg.norm(alpha * y))


def test_conjugate_gradients_reach_their_tolerance_on_a_noisy_take_with_gaps(walk):
    # one solve of the smoothed objective at the engine's lambda, with the committed CMU
    # bases: the two-level preconditioner converges to CG_TOL in about 20 steps, where the
    # banded one alone stops at CG_STEPS short of it
    model = registry.create("mssa").models_["angles"]
    rng = np.random.default_rng(4)
    X = walk.channels[:, model.columns]
    X = np.concatenate([X, X[::-1]] * 3)  # forwards and backwards: 2,058 frames
    u = (X - np.median(X, axis=0)) / model.scale + rng.normal(0.0, 0.3, X.shape)
    seen = rng.random(u.shape) > 0.02
    for start in range(100, len(u), 400):  # 1/2-s gaps in a third of the channels
        seen[start : start + 60, rng.choice(u.shape[1], u.shape[1] // 3, replace=False)] = False
    alpha = seen / 0.3**2
    mu = np.full(u.shape[1], 50.0)
    z = robust_filter(u, alpha, model.projector, 3.0, 1.0, robust=False, method="cg", smoothness=mu).z
    assert relative_residual(z, u, alpha, model.projector, 3.0, mu) <= 1.01 * CG_TOL


@pytest.mark.parametrize("window", [2, 3, 20])
def test_smoothed_solves_run_for_any_window(window):
    # the coarse grid's bands are as high as the window's bases term or the smoothness
    # term needs, whichever is higher
    rng = np.random.default_rng(window)
    L, F = 3, 300
    E = np.linalg.qr(rng.normal(size=(L * window, L * window // 2 + 1)))[0]
    projector = WindowProjector(E, window)
    u = np.cumsum(rng.normal(size=(F, L)), axis=0) * 0.1 + rng.normal(0.0, 0.2, (F, L))
    seen = rng.random((F, L)) > 0.1
    alpha, mu = seen / 0.2**2, np.full(L, 20.0)
    z = robust_filter(u, alpha, projector, 3.0, 1.0, robust=False, method="cg", smoothness=mu).z
    assert relative_residual(z, u, alpha, projector, 3.0, mu) <= 1.01 * CG_TOL
