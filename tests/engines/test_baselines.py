"""The baseline engines (issue 3): gaussian, lerp, spline, butterworth, kalman,
kalman-learned, and Mall's lerp>gaussian pipeline, on short real clips with noise and
gaps made here with numpy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from workbench.core.channels import interpolate_gaps, unwrap_deg
from workbench.core.motion import Motion, Observation, angle_columns
from workbench.core.rotations import wrap_deg
from workbench.engine import EngineError, NotFittedError
from workbench.io import read_bvh
from workbench.registry import create
from workbench.testing.conformance import check_engine

BASELINES = ["gaussian", "gaussian:sigma_ms=125", "lerp", "spline", "butterworth", "kalman", "lerp>gaussian"]
TRAIN = ["walk/02_01", "run/09_01", "jump/02_04"]  # training split (subjects 02, 09)
HELD_OUT = ["walk/16_21", "run/35_24", "jog/16_35"]  # test split (subjects 16, 35)


# -- data -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cmu(data_root):
    cache: dict[str, Motion] = {}

    def load(clip: str) -> Motion:
        if clip not in cache:
            cache[clip] = read_bvh(data_root / "cmu" / f"{clip}.bvh").slice(1)
        return cache[clip]

    return load


@pytest.fixture(scope="module")
def clip(cmu):
    """343 frames of CMU walk 02_01 (31 joints, 120 fps)."""
    return cmu("walk/02_01")


@pytest.fixture(scope="module")
def learned(cmu):
    return create("kalman-learned", pretrained=False).fit([cmu(c) for c in TRAIN])


def noisy(motion: Motion, level: float = 0.5, seed: int = 0) -> Motion:
    """Gaussian noise of ``level`` x channel std on the scored joint-angle channels."""
    rng = np.random.default_rng(seed)
    X = motion.channels
    cols = angle_columns(motion.skeleton)
    X[:, cols] += rng.normal(size=(motion.n_frames, cols.size)) * level * X[:, cols].std(axis=0)
    return motion.with_channels(X)


def with_gaps(motion: Motion, seed: int = 1) -> Observation:
    """Three joints missing for 40 frames, 2 % of samples missing at random (root kept)."""
    rng = np.random.default_rng(seed)
    obs = np.ones((motion.n_frames, motion.skeleton.n_joints), bool)
    for j in (3, 12, 25):
        s = int(rng.integers(10, motion.n_frames - 50))
        obs[s : s + 40, j] = False
    obs[rng.random(obs.shape) < 0.02] = False
    obs[:, 0] = True
    return Observation(motion, obs)


def angle_rms(a: Motion, b: Motion) -> float:
    cols = angle_columns(a.skeleton)
    d = wrap_deg(a.channels[:, cols] - b.channels[:, cols])
    return float(np.sqrt(np.mean(d**2)))


def rts_reference(Y, observed, r, A1, A2, c, Q):
    """Forward Kalman filter + backward RTS recursion (textbook form) for one group of
    b channels with state (x_t, x_{t-1}); near-flat prior on the first state."""
    F, b = Y.shape
    T = np.block([[A1, A2], [np.eye(b), np.zeros((b, b))]])
    off = np.concatenate([c, np.zeros(b)])
    Qs = np.zeros((2 * b, 2 * b))
    Qs[:b, :b] = Q
    x, P = np.zeros(2 * b), np.eye(2 * b) * 1e10
    xs, Ps, xp, Pp = [], [], [], []
    for t in range(F):
        if t > 0:
            x, P = T @ x + off, T @ P @ T.T + Qs
        xp.append(x), Pp.append(P)
        o = np.flatnonzero(observed[t])
        if o.size:
            H = np.eye(2 * b)[o]
            S = H @ P @ H.T + np.diag(r[o])
            K = P @ H.T @ np.linalg.inv(S)
            x, P = x + K @ (Y[t, o] - H @ x), P - K @ H @ P
        xs.append(x), Ps.append(P)
    out = [xs[-1]]
    for t in range(F - 2, -1, -1):
        Gk = Ps[t] @ T.T @ np.linalg.inv(Pp[t + 1])
        out.append(xs[t] + Gk @ (out[-1] - xp[t + 1]))
    return np.array(out[::-1])[:, :b]


# -- every engine ---------------------------------------------------------------------
@pytest.mark.parametrize("spec", BASELINES)
def test_conformance(spec, clip, kick):
    check_engine(lambda: create(spec, pretrained=False), clip.slice(0, 150), kick.slice(0, 150))


def test_conformance_learned(learned, clip, kick):
    check_engine(lambda: learned, clip.slice(0, 150), kick.slice(0, 150))


@pytest.mark.parametrize("spec", BASELINES + ["kalman-learned"])
def test_gaps_wrapping_and_input_untouched(spec, clip, learned):
    """Gappy noisy input with an angle wrapping through +-180: finite output of the same
    shape, on the input's angle branch, input unchanged."""
    X = noisy(clip).channels
    X[:, 3 + 3 * 5] = (np.linspace(150.0, 230.0, clip.n_frames) + 180.0) % 360.0 - 180.0
    obs = with_gaps(clip.with_channels(X))
    before = obs.motion.channels.copy()
    engine = learned if spec == "kalman-learned" else create(spec)
    out = engine.clean(obs).motion
    assert np.array_equal(obs.motion.channels, before, equal_nan=True)
    assert out.n_frames == clip.n_frames and out.fps == clip.fps and out.skeleton.same_layout(clip.skeleton)
    assert np.isfinite(out.channels).all()
    mask = obs.channel_observed
    step = np.abs(out.channels - obs.motion.channels)[mask]
    assert step.max() < 180.0, "angles must come back on the input's branch"


@pytest.mark.parametrize("spec", ["gaussian", "butterworth", "kalman", "lerp>gaussian"])
def test_denoisers_reduce_angle_error(spec, clip):
    obs = Observation(noisy(clip, 0.5))
    before = angle_rms(obs.motion, clip)
    after = angle_rms(create(spec).clean(obs).motion, clip)
    assert after < 0.45 * before, (spec, before, after)


def test_spec_round_trip():
    for spec in BASELINES + [
        "gaussian:sigma_ms=125.0",
        "butterworth:cutoff_hz=8.0,order=2",
        "kalman:measurement_noise_deg2=4.0,process_noise_deg2_per_frame4=0.01",
        "kalman-learned:correlation_shrinkage=0.25,learned_dynamics=True",
        "lerp>gaussian:sigma_ms=125.0",
    ]:
        e = create(spec, pretrained=False)
        assert create(e.spec, pretrained=False).spec == e.spec
    assert create("gaussian").params.sigma_ms == 58.0
    assert create("lerp>gaussian:sigma_ms=58").spec == "lerp>gaussian"


@pytest.mark.parametrize(
    "spec",
    [
        "gaussian:sigma_ms=0",
        "gaussian:sigma_ms=-3",
        "butterworth:cutoff_hz=-1",
        "butterworth:order=0",
        "kalman:measurement_noise_deg2=-1",
        "kalman-learned:correlation_shrinkage=2",
    ],
)
def test_bad_parameters_are_engine_errors(spec):
    with pytest.raises(EngineError):
        create(spec, pretrained=False)


# -- lerp and spline ------------------------------------------------------------------
@pytest.mark.parametrize("spec,kind", [("lerp", "linear"), ("spline", "cubic")])
def test_interpolators_keep_observed_and_fill_with_the_interpolant(spec, kind, clip):
    obs = with_gaps(noisy(clip))
    out = create(spec).clean(obs).motion.channels
    mask = obs.channel_observed
    X = obs.motion.channels
    assert np.array_equal(out[mask], X[mask]), "observed samples must come back bit for bit"
    j = 12
    c = 3 + 3 * j + 1
    t = np.arange(clip.n_frames)
    o = obs.observed[:, j]
    assert np.abs(np.diff(X[o, c])).max() < 180.0  # no wrapping in this channel
    if kind == "linear":
        expected = np.interp(t, t[o], X[o, c])
    else:
        expected = np.interp(t, t[o], X[o, c])
        inside = (t > t[o][0]) & (t < t[o][-1])
        expected[inside] = CubicSpline(t[o], X[o, c], bc_type="natural")(t[inside])
    np.testing.assert_allclose(out[:, c], expected, atol=1e-9)


def test_cubic_gap_filling_matches_column_by_column_splines():
    rng = np.random.default_rng(0)
    X = np.cumsum(rng.normal(size=(200, 9)), axis=0)
    obs = rng.random(X.shape) > 0.3
    obs[:, 1] = obs[:, 2] = obs[:, 0]  # a shared mask, as for a joint's three angles
    obs[:197, 5] = False  # 3 observations: linear
    out = interpolate_gaps(X, obs, "cubic")
    t = np.arange(200)
    for c in range(9):
        o = obs[:, c]
        ref = np.interp(t, t[o], X[o, c])
        if o.sum() >= 4:
            inside = (t > t[o][0]) & (t < t[o][-1])
            ref[inside] = CubicSpline(t[o], X[o, c], bc_type="natural")(t[inside])
        np.testing.assert_allclose(out[:, c], ref, atol=1e-9)


def test_unwrap_deg_matches_numpy_unwrap():
    rng = np.random.default_rng(0)
    X = np.cumsum(rng.normal(scale=40.0, size=(300, 8)), axis=0)
    X = (X + 180.0) % 360.0 - 180.0
    X[:, 0] = 10.0
    obs = rng.random(X.shape) > 0.1
    Xn = np.where(obs, X, np.nan)
    ours = unwrap_deg(Xn, obs)
    ff = np.array(Xn)
    for c in range(8):  # reference: forward fill then np.unwrap
        o = obs[:, c]
        idx = np.maximum.accumulate(np.where(o, np.arange(300), -1))
        idx[idx < 0] = np.argmax(o)
        ff[:, c] = X[idx, c]
    ref = np.unwrap(ff, period=360.0, axis=0)
    ref[~obs] = np.nan
    np.testing.assert_array_equal(ours, ref)


def test_an_outlier_half_a_turn_off_leaves_no_whole_turn_in_the_smoothed_take(walk):
    """A joint turning slowly through +-180 degrees with one sample 179.5 degrees off:
    np.unwrap would put the rest of the take a whole turn away, and the smoother would
    blur that step into up to 180 degrees of error around it; with the robust unwrap the
    outlier is one sample, its weight in the kernel a few degrees."""
    m = walk.slice(0, 120)
    X = m.channels
    truth = np.linspace(150.0, 230.0, m.n_frames)
    X[:, 3 + 3 * 5] = (truth + 180.0) % 360.0 - 180.0
    clean = m.with_channels(X)
    X[60, 3 + 3 * 5] = (X[60, 3 + 3 * 5] - 179.5 + 180.0) % 360.0 - 180.0
    out = create("gaussian").clean(Observation(m.with_channels(X))).motion.channels[:, 3 + 3 * 5]
    ref = create("gaussian").clean(Observation(clean)).motion.channels[:, 3 + 3 * 5]
    err = np.abs((out - ref + 180.0) % 360.0 - 180.0)
    assert err.max() < 15.0


@pytest.mark.parametrize("spec", ["gaussian", "kalman", "butterworth", "lerp>gaussian", "mssa", "ebf", "cae"])
def test_a_joint_passing_through_gimbal_lock_is_smoothed_as_one_rotation(spec, walk):
    """An arm raised through the lock of its Euler order: the exporter's triple jumps to
    the other triple of the same rotation, (a, b, c) -> (a + 180, 180 - b, c + 180). Each
    channel smoothed on its own made that a hand turned 100 degrees and more; the engines
    see the triple continued and write the take's own triples back."""
    from workbench.core.rotations import euler_to_matrix, matrix_to_euler

    m = walk.slice(1, 241)
    j = m.skeleton.names.index("LeftArm")
    order = m.skeleton.rotation_order(j)
    lift = np.linspace(60.0, 120.0, m.n_frames)  # the middle axis through 90 degrees
    turns = np.stack([np.full(m.n_frames, 30.0), lift, np.full(m.n_frames, 20.0)], axis=1)
    triples = matrix_to_euler(euler_to_matrix(turns, order), order)
    X = m.channels
    X[:, 3 + 3 * j : 6 + 3 * j] = triples
    take = m.with_channels(X)
    assert np.abs(np.diff(triples[:, 0])).max() > 170.0  # the take's own triples jump
    out = create(spec).clean(Observation(take)).motion.channels[:, 3 + 3 * j : 6 + 3 * j]
    R, Q = euler_to_matrix(triples, order), euler_to_matrix(out, order)
    turned = np.degrees(np.arccos(np.clip((np.einsum("fij,fij->f", R, Q) - 1.0) / 2.0, -1.0, 1.0)))
    assert turned.max() < 3.0
    near = np.abs(wrap_deg(out - triples)).max(axis=1) < 10.0  # on the take's triples, not the other ones
    assert near.mean() > 0.95


def test_a_jump_at_gimbal_lock_is_told_from_noise_and_from_a_gap(walk):
    """The reading goes through the lock only where the jump is plain: not where the
    joint is as noisy as the two triples are near, not across a gap (the motion may have
    turned that way on its own), not at an outlier far from the lock."""
    from workbench.core.rotations import euler_to_matrix, matrix_to_euler
    from workbench.engine.signal import euler_flips

    m = walk.slice(1, 241)
    j = m.skeleton.names.index("LeftArm")
    order = m.skeleton.rotation_order(j)
    turns = np.stack([np.full(240, 30.0), np.linspace(60.0, 120.0, 240), np.full(240, 20.0)], axis=1)
    X = m.channels
    X[:, 3 + 3 * j : 6 + 3 * j] = matrix_to_euler(euler_to_matrix(turns, order), order)
    flips = euler_flips(Observation(m.with_channels(X)))
    assert list(flips.joints) == [j] and flips.other[:, 0].sum() == 120  # the second half read as the other triple
    noisy = X.copy()
    noisy[:, 3 + 3 * j : 6 + 3 * j] += np.random.default_rng(0).normal(scale=20.0, size=(240, 3))
    assert euler_flips(Observation(m.with_channels(noisy))) is None
    observed = np.ones((240, m.skeleton.n_joints), bool)
    observed[110:130, j] = False  # the lock passed inside a gap
    assert euler_flips(Observation(m.with_channels(X), observed)) is None
    far = X.copy()
    far[:, 3 + 3 * j : 6 + 3 * j] = matrix_to_euler(euler_to_matrix(turns - [0.0, 60.0, 0.0], order), order)
    far[100, 3 + 3 * j : 6 + 3 * j] += [170.0, 0.0, 170.0]  # an outlier nearer the other triple, far from the lock
    assert euler_flips(Observation(m.with_channels(far))) is None


# -- gaussian -------------------------------------------------------------------------
def _one_channel(motion: Motion, values: np.ndarray, joint: int = 7, k: int = 1) -> Motion:
    X = motion.channels
    X[:, 3 + 3 * joint + k] = values
    return motion.with_channels(X)


def test_gaussian_constant_with_holes_stays_constant(clip):
    m = _one_channel(clip, np.full(clip.n_frames, 17.5))
    obs = np.ones((clip.n_frames, clip.skeleton.n_joints), bool)
    obs[::7, 7] = False
    obs[100:220, 7] = False  # a gap far wider than the kernel
    for spec in ("gaussian", "gaussian:sigma_ms=125"):
        out = create(spec).clean(Observation(m, obs)).motion.channels[:, 3 + 3 * 7 + 1]
        np.testing.assert_allclose(out, 17.5, atol=1e-9)  # edges included: no pull towards 0


def test_gaussian_normalised_convolution_ignores_missing_samples(clip):
    t = np.arange(clip.n_frames, dtype=float)
    x = 20.0 * np.sin(2 * np.pi * t / 90.0)
    obs = np.ones((clip.n_frames, clip.skeleton.n_joints), bool)
    obs[150:156, 7] = False
    obs[::11, 7] = False
    X = clip.channels
    X[:, 3 + 3 * 7 + 1] = x
    X[~obs[:, 7], 3 + 3 * 7 + 1] = 1e6  # garbage in the missing samples: must not matter
    out = create("gaussian").clean(Observation(clip.with_channels(X), obs)).motion.channels[:, 3 + 3 * 7 + 1]
    sigma = 0.058 * clip.fps
    i = np.arange(-int(4 * sigma + 0.5), int(4 * sigma + 0.5) + 1)
    g = np.exp(-0.5 * (i / sigma) ** 2)
    m = obs[:, 7].astype(float)
    expected = np.convolve(m * x, g, "same") / np.convolve(m, g, "same")
    np.testing.assert_allclose(out, expected, atol=0.01)  # gap samples weigh 1e-3, not 0


@pytest.mark.parametrize("sigma_ms", [58.0, 125.0])
def test_gaussian_sigma_is_in_milliseconds(sigma_ms, clip):
    impulse = np.zeros(clip.n_frames)
    impulse[170] = 1.0
    engine = create(f"gaussian:sigma_ms={sigma_ms}")
    res = engine.clean(Observation(_one_channel(clip, impulse)))
    h = res.motion.channels[:, 3 + 3 * 7 + 1]
    t = np.arange(clip.n_frames)
    assert h.sum() == pytest.approx(1.0, abs=1e-9)
    std = np.sqrt(np.sum(h * (t - 170) ** 2))
    assert std == pytest.approx(sigma_ms / 1000.0 * 120.0, rel=0.01)
    assert res.diagnostics["filter_sigma_frames"].shape == (clip.n_frames, 3 + 3 * clip.skeleton.n_joints)
    assert np.all(res.diagnostics["filter_sigma_frames"] == pytest.approx(sigma_ms * 0.12))


# -- butterworth ----------------------------------------------------------------------
def test_butterworth_passes_low_and_stops_high_frequencies(clip):
    t = np.arange(clip.n_frames) / clip.fps
    mid = slice(60, -60)
    for f_hz, lo, hi in ((2.0, 0.95, 1.01), (20.0, 0.0, 0.01)):
        wave = 10.0 * np.sin(2 * np.pi * f_hz * t)
        out = create("butterworth").clean(Observation(_one_channel(clip, wave))).motion.channels[:, 3 + 3 * 7 + 1]
        gain = np.abs(out[mid]).max() / 10.0
        assert lo <= gain <= hi, (f_hz, gain)


def test_butterworth_clear_errors(clip):
    with pytest.raises(EngineError, match="Nyquist"):
        create("butterworth:cutoff_hz=60").clean(Observation(clip))
    with pytest.raises(EngineError, match="frames"):
        create("butterworth").clean(Observation(clip.slice(0, 12)))


# -- kalman ---------------------------------------------------------------------------
@pytest.mark.parametrize("spec", ["kalman", "kalman-learned"])
def test_kalman_fills_a_constant_velocity_ramp_exactly_and_holds_its_ends(spec, clip, learned):
    """Inside the take the model's path is the ramp itself; beyond an angle's first and
    last observations the value there is held, not run on at the ramp's velocity, also
    where the ramp wraps round +-180 degrees; the root's position runs on."""
    ramp = -40.0 + 0.35 * np.arange(clip.n_frames)
    wrapped = wrap_deg(170.0 + 0.35 * np.arange(clip.n_frames))
    obs = np.ones((clip.n_frames, clip.skeleton.n_joints), bool)
    obs[120:200, 7] = False
    obs[:15, 7] = obs[-20:, 7] = False
    engine = learned if spec == "kalman-learned" else create(spec)
    for channel in (ramp, wrapped):
        out = engine.clean(Observation(_one_channel(clip, channel), obs)).motion.channels[:, 3 + 3 * 7 + 1]
        np.testing.assert_allclose(wrap_deg(out[15:-20] - channel[15:-20]), 0.0, atol=1e-4)
        np.testing.assert_allclose(wrap_deg(out[:15] - channel[15]), 0.0, atol=1e-4)
        np.testing.assert_allclose(wrap_deg(out[-20:] - channel[-21]), 0.0, atol=1e-4)
    X = clip.channels
    X[:, 0] = 0.5 * np.arange(clip.n_frames)  # the root walks along x at constant speed
    walk = clip.with_channels(X)
    obs[:, 0] = obs[:, 7]
    out = engine.clean(Observation(walk, obs)).motion.channels[:, 0]
    np.testing.assert_allclose(out, walk.channels[:, 0], atol=1e-3)


def test_kalman_noise_estimate_for_known_white_noise():
    rng = np.random.default_rng(5)
    t = np.arange(2000) / 120.0
    smooth = 30.0 * np.sin(2 * np.pi * 0.7 * t)[:, None] + 10.0 * np.sin(2 * np.pi * 1.9 * t[:, None] + np.arange(4))
    from workbench.engine.smoothing import estimate_noise

    for std in (0.5, 2.0, 5.0):
        Y = smooth + rng.normal(size=smooth.shape) * std
        q, r = estimate_noise(Y, np.ones(Y.shape, bool))
        assert np.all(np.abs(r / std**2 - 1.0) < 0.2), r / std**2


def test_mean_square_noise_estimate_for_heavy_tailed_noise():
    """Noise with heavy tails (here Laplace): the median-based estimate misses much of
    the variance, the mean-square one does not; both hold for Gaussian noise."""
    from workbench.engine.smoothing import measurement_variance

    rng = np.random.default_rng(6)
    t = np.arange(4000) / 120.0
    smooth = 30.0 * np.sin(2 * np.pi * 0.7 * t)[:, None] + np.zeros((1, 3))
    seen = np.ones(smooth.shape, bool)
    seen[100:140, 1] = False
    laplace = smooth + rng.laplace(scale=2.0 / np.sqrt(2.0), size=smooth.shape)  # variance 4
    gauss = smooth + rng.normal(scale=2.0, size=smooth.shape)
    assert np.all(measurement_variance(laplace, seen) < 0.8 * 4.0)
    np.testing.assert_allclose(measurement_variance(laplace, seen, robust=False), 4.0, rtol=0.1)
    for robust in (True, False):
        np.testing.assert_allclose(measurement_variance(gauss, seen, robust=robust), 4.0, rtol=0.1)


@pytest.mark.parametrize("fps, step", [(30, 4.0), (60, 2.0), (25, 4.8)])
def test_the_noise_of_a_take_resampled_up_is_measured_on_its_captured_frames(fps, step):
    """Linear interpolation hides the noise from the frames between the captured ones:
    on all frames the estimate is next to none; on the captured ones (``step`` apart) it
    is the capture's (exactly at a whole step; at 4.8 the nearest frames hold a little
    interpolation), returned per frame of the resampled channels, ``step`` times it."""
    from workbench.engine.smoothing import measurement_variance

    rng = np.random.default_rng(7)
    frames = np.arange(1000)
    captured = 30.0 * np.sin(2 * np.pi * 0.7 * frames / fps)[:, None] + rng.normal(scale=2.0, size=(1000, 3))
    t = np.arange(0.0, 999 + 1e-9, 1.0 / step)
    resampled = np.column_stack([np.interp(t, frames, captured[:, c]) for c in range(3)])
    seen = np.ones(resampled.shape, bool)
    assert np.all(measurement_variance(resampled, seen) < 0.01)
    per_captured = measurement_variance(resampled, seen, step=step) / step
    if step % 1 == 0:
        np.testing.assert_allclose(per_captured, measurement_variance(captured, np.ones(captured.shape, bool)))
    np.testing.assert_allclose(per_captured, 4.0, rtol=0.25)


@pytest.mark.parametrize(
    "corruption, quieter",
    [("angular:0.5", True), ("angular:0.1", True), ("spatial:1", False), ("angular:0.5+outliers:0.05", False)],
)
def test_angle_levers_keep_the_reference_where_the_noise_is_in_the_angles(corruption, quieter, clip):
    """The feet's observed angles tell their direction better than the toe's observed
    position does under angle noise (the toe carries the noise of the whole leg), not
    under position noise, and not when the angles have outliers: IK keeps them at the
    reference in their observed frames only then, and turns the bones towards the
    reference's Euler angles wherever the noise is not in the positions. Only then too
    it weighs the reference against the aim of the joints it measures, by variances."""
    from workbench.corruption import parse_corruption
    from workbench.engine.signal import bridge_gaps
    from workbench.engine.smoothing import ik_reference

    sk = clip.skeleton
    feet = [sk.index("LeftFoot"), sk.index("RightFoot")]
    obs = parse_corruption(corruption).apply(clip, seed=0)
    bridged = bridge_gaps(obs)
    positions = obs.motion.with_channels(bridged).positions
    _, ik = ik_reference(sk, bridged, obs.observed, positions, short_lever_cm=5.0, angle_lever_cm=30.0)
    np.testing.assert_array_equal(ik["reference_frames"][:, feet], obs.observed[:, feet] & quieter)
    assert ik["reference_measured"].all() == corruption.startswith("angular")
    weighed = np.isfinite(ik["aim_variance"])  # IK weighs the reference against the aim
    assert weighed[feet].all() == quieter and weighed.any() == quieter
    assert (ik["reference_variance"][weighed] > 0).all()
    _, ik = ik_reference(sk, bridged, obs.observed, positions, short_lever_cm=5.0, angle_lever_cm=10.0)
    assert not ik["reference_frames"][:, feet].any()  # the feet's 13 cm are beyond the lever


def test_a_take_is_taken_for_position_noise_only_clear_of_the_angle_noise_range(clip):
    """The threshold lies midway between the validation takes' largest mean log ratio
    under angle noise (-0.05) and their least under position noise (0.68): a Mixamo
    retarget at +0.03 under ``angular:0.5`` is angle noise."""
    from workbench.engine.smoothing import _noise_is_in_positions

    position = np.full(12, 1.0)  # variances, far above the floor
    assert not _noise_is_in_positions(clip.skeleton, position * np.exp(0.03), position)
    assert _noise_is_in_positions(clip.skeleton, position * np.exp(0.68), position)
    assert not _noise_is_in_positions(clip.skeleton, position * np.exp(0.68), position * 1e-12)  # below the floor


@pytest.mark.parametrize(
    "corruption, bridge",
    [
        ("gaps:0.02", True),
        ("angular:0.5+gaps:0.02", True),
        ("spatial:0.2+gaps:0.02", True),
        ("spatial:1+gaps:0.02", False),
        ("angular:0.5+outliers:0.05", False),
        ("outliers:0.02", False),
    ],
)
def test_angles_bridge_holes_unless_the_noise_is_in_the_positions_or_has_outliers(corruption, bridge, clip):
    """A take's holes are left to the angles' smoother when it is clean, when its noise
    is in the angles or small, not under position noise of 1 cm, nor with outliers."""
    from workbench.corruption import parse_corruption
    from workbench.engine.signal import bridge_gaps
    from workbench.engine.smoothing import angles_bridge_holes

    obs = parse_corruption(corruption).apply(clip, seed=0)
    bridged = bridge_gaps(obs)
    positions = obs.motion.with_channels(bridged).positions
    assert angles_bridge_holes(clip.skeleton, bridged, obs.observed, positions, 5.0) is bridge


@pytest.mark.parametrize(
    "corruption, quiet",
    [
        ("gaps:0.02", True),
        ("angular:0.1", True),
        ("spatial:0.2", True),
        ("angular:0.9", False),
        ("spatial:1", False),
        ("outliers:0.01", False),
    ],
)
def test_angles_are_quiet_below_half_a_centimetre_of_noise(corruption, quiet, clip):
    """Quiet: less than 0.5 cm of angle noise, outliers included, as the descendants see it."""
    from workbench.corruption import parse_corruption
    from workbench.engine.signal import bridge_gaps
    from workbench.engine.smoothing import angles_are_quiet

    obs = parse_corruption(corruption).apply(clip, seed=0)
    assert angles_are_quiet(clip.skeleton, bridge_gaps(obs), obs.observed) is quiet


@pytest.mark.parametrize("level", [0.1, 0.5, 0.9])
def test_kalman_noise_estimate_on_mocap(level, clip):
    obs = Observation(noisy(clip, level, seed=2))
    q, r = create("kalman").estimate_noise(obs)
    cols = angle_columns(clip.skeleton)
    true_std = level * clip.channels[:, cols].std(axis=0)
    live = true_std > 0
    ratio = np.sqrt(r[cols][live]) / true_std[live]
    assert abs(np.median(ratio) - 1.0) < 0.2, np.median(ratio)
    assert angle_rms(create("kalman").clean(obs).motion, clip) < angle_rms(obs.motion, clip)


def test_kalman_fixed_noise_parameters(clip):
    obs = Observation(noisy(clip))
    light = create("kalman:measurement_noise_deg2=0.01,process_noise_deg2_per_frame4=100").clean(obs).motion
    assert angle_rms(light, obs.motion) < 0.2  # trusts the data: hardly smooths
    heavy = create("kalman:process_noise_deg2_per_frame4=0.0001").clean(obs).motion
    assert angle_rms(heavy, obs.motion) > angle_rms(light, obs.motion)


def test_the_smoother_bridges_a_hole_nearer_a_smooth_truth_than_a_line():
    """smooth_and_fill's path across a hole of a clean channel (what cae bridges its holes
    with) is a spline through the samples around it: 10x nearer a smooth truth than the
    line across, and the observed samples stay (a clean channel is interpolated)."""
    from workbench.engine.smoothing import smooth_and_fill

    t = np.arange(240.0)
    truth = np.column_stack([np.sin(t / 12.0), np.cos(t / 20.0)])
    observed = np.ones(truth.shape, bool)
    observed[50:56, 0] = False  # a short hole
    observed[100:130, 1] = False  # a partial-body hole of a slower channel
    line, smooth = interpolate_gaps(truth, observed), smooth_and_fill(truth, observed)
    np.testing.assert_allclose(smooth[observed], truth[observed], atol=5e-3)
    for hole in (np.s_[50:56, 0], np.s_[100:130, 1]):
        assert np.abs(smooth[hole] - truth[hole]).max() < 0.1 * np.abs(line[hole] - truth[hole]).max()


def test_cv_smoother_equals_rts_recursion():
    from workbench.engine.smoothing import cv_smooth

    rng = np.random.default_rng(1)
    F, D = 120, 5
    Y = np.cumsum(np.cumsum(rng.normal(size=(F, D)), 0), 0) * 0.1 + rng.normal(size=(F, D))
    obs = np.ones((F, D), bool)
    obs[30:60, 1] = False
    obs[:8, 2] = False
    obs[rng.random(F) < 0.2, 3] = False
    q, r = rng.uniform(0.01, 1.0, D), rng.uniform(0.1, 2.0, D)
    ours = cv_smooth(Y, obs, q, r)  # DCT path for columns 0 and 4, banded for the rest
    for d in range(D):
        ref = rts_reference(
            Y[:, d : d + 1], obs[:, d : d + 1], r[d : d + 1], np.eye(1) * 2, -np.eye(1), np.zeros(1), np.eye(1) * q[d]
        )[:, 0]
        np.testing.assert_allclose(ours[:, d], ref, atol=1e-5 * np.abs(ref).max())


def test_the_banded_smoother_solves_a_few_columns_at_a_time_with_the_same_bits(monkeypatch):
    """A long take's gappy columns are solved BANDED_UNKNOWNS at a time: any split of
    them gives the one solve's values exactly (their systems do not couple)."""
    from workbench.engine import smoothing

    rng = np.random.default_rng(3)
    F, D = 200, 7
    Y = np.cumsum(rng.normal(size=(F, D)), 0)
    obs = rng.random((F, D)) > 0.1
    q, r = rng.uniform(0.01, 1.0, D), rng.uniform(0.1, 2.0, D)
    whole = smoothing.cv_smooth(Y, obs, q, r)
    for unknowns in (1, 2 * F, 3 * F + 5):  # one column a solve (at least), two, three
        monkeypatch.setattr(smoothing, "BANDED_UNKNOWNS", unknowns)
        np.testing.assert_array_equal(smoothing.cv_smooth(Y, obs, q, r), whole)


def test_a_column_too_ill_conditioned_for_cholesky_gets_the_line_through_its_samples():
    """A channel at rest (the variance floors) seen in four frames close together of a
    2,251-frame take: its system defeats banded Cholesky, so it gets the line through its
    samples (the smoother's limit), and the other columns of the solve keep their values;
    in a shorter take the solve goes through and stays on the line."""
    from workbench.engine import smoothing

    F = 2251
    Y = np.zeros((F, 2))
    Y[:, 0] = 12.5
    Y[:, 1] = np.sin(np.arange(F) / 40.0)
    obs = np.zeros((F, 2), bool)
    obs[1000:1004, 0] = True
    obs[::3, 1] = True
    q, r = np.array([1e-18, 1e-3]), np.array([1e-10, 1e-2])
    with pytest.raises(np.linalg.LinAlgError):
        smoothing._solve_banded(smoothing.second_difference_band(F), Y[:, :1], obs[:, :1], q[:1], r[:1])
    out = smoothing.cv_smooth(Y, obs, q, r)
    np.testing.assert_allclose(out[:, 0], 12.5, atol=1e-9)
    np.testing.assert_array_equal(out[:, 1], smoothing.cv_smooth(Y[:, 1:], obs[:, 1:], q[1:], r[1:])[:, 0])
    # 1,200 frames and samples a little off the line: Cholesky gets through, and solving for
    # the departure from the line keeps the solution exact (against a dense least-squares solve)
    F, seen = 1200, np.zeros(1200, bool)
    seen[600:604] = True
    y = 12.5 + np.where(seen, 1e-5 * np.random.default_rng(1).normal(size=F), 0.0)
    D2 = np.diff(np.eye(F), 2, axis=0)
    system = np.vstack([np.eye(F)[seen] / np.sqrt(r[0]), D2 / np.sqrt(q[0])])
    exact = np.linalg.lstsq(system, np.r_[y[seen] / np.sqrt(r[0]), np.zeros(F - 2)], rcond=None)[0]
    np.testing.assert_allclose(smoothing.cv_smooth(y[:, None], seen[:, None], q[0], r[0])[:, 0], exact, atol=1e-6)


def test_coupled_smoother_equals_rts_recursion():
    from engines.kalman.coupled import coupled_smooth

    rng = np.random.default_rng(2)
    F, b = 80, 3
    A1 = 2 * np.eye(b) + 0.05 * rng.normal(size=(b, b))
    A2 = -np.eye(b) + 0.05 * rng.normal(size=(b, b))
    c = rng.normal(size=b) * 0.1
    L = rng.normal(size=(b, b))
    Q = L @ L.T + 0.1 * np.eye(b)
    r = rng.uniform(0.2, 1.0, b)
    Y = np.cumsum(rng.normal(size=(F, b)), 0)
    obs = np.ones((F, b), bool)
    obs[20:35] = False
    obs[rng.random(F) < 0.1, 1] = False
    ours = coupled_smooth(Y[None], obs[None], r[None], A1[None], A2[None], c[None], np.linalg.inv(Q)[None])[0]
    ref = rts_reference(Y, obs, r, A1, A2, c, Q)
    np.testing.assert_allclose(ours, ref, atol=1e-5 * np.abs(ref).max())


# -- kalman-learned -------------------------------------------------------------------
def test_learned_kalman_at_least_matches_kalman_on_held_out_clips(cmu, learned):
    kalman = create("kalman")
    errors = []
    for i, name in enumerate(HELD_OUT):
        truth = cmu(name).slice(0, 300)
        obs = Observation(noisy(truth, 0.5, seed=10 + i))
        errors.append((angle_rms(kalman.clean(obs).motion, truth), angle_rms(learned.clean(obs).motion, truth)))
    e = np.array(errors)
    # what holds (checked at 0.1 / 0.5 / 0.9 noise, with and without gaps): the learnt
    # process-noise correlation gives 1-3 % lower error without gaps, about equal with them
    assert e[:, 1].mean() < e[:, 0].mean(), e
    assert np.all(e[:, 1] < 1.02 * e[:, 0]), e


def test_learned_dynamics_variant_runs(cmu, learned):
    engine = create("kalman-learned:learned_dynamics=true", pretrained=False)
    engine.load_state_arrays(learned.state_arrays(), {})
    engine.skeleton_signature_, engine.fps_ = learned.skeleton_signature_, learned.fps_
    truth = cmu(HELD_OUT[0]).slice(0, 200)
    out = engine.clean(with_gaps(noisy(truth))).motion
    assert np.isfinite(out.channels).all()


def test_learned_kalman_refuses_other_skeletons(learned, kick, clip):
    with pytest.raises(EngineError, match="skeleton") as err:
        learned.clean(Observation(kick.slice(0, 100)))
    assert "43 body joints" in str(err.value)
    with pytest.raises(EngineError, match="skeleton"):
        create("kalman-learned", pretrained=False).fit([clip, kick])


def test_learned_kalman_needs_fitting(clip):
    with pytest.raises(NotFittedError):
        create("kalman-learned", pretrained=False).clean(Observation(clip))


def test_learned_kalman_save_load_round_trip(learned, clip, tmp_path):
    learned.save(tmp_path / "weights")
    again = create("kalman-learned", pretrained=False).load(tmp_path / "weights")
    assert again.skeleton_signature_ == learned.skeleton_signature_
    obs = with_gaps(noisy(clip))
    np.testing.assert_array_equal(again.clean(obs).motion.channels, learned.clean(obs).motion.channels)


def test_learned_kalman_weights_live_in_the_package():
    engine = create("kalman-learned", pretrained=False)
    assert engine.default_weights_dir().parts[-4:] == ("engines", "kalman", "weights", "kalman-learned")


def test_a_gaussian_wider_than_the_take_is_its_mean_and_costs_no_more(walk):
    """A kernel never reaches past the take, so it is cut there (a 1e9 ms sigma once
    tried to allocate hundreds of GiB): with every frame in reach, each is the mean."""
    short = walk.slice(0, 50)
    out = create("gaussian:sigma_ms=1e9").clean(Observation(short)).motion.channels
    np.testing.assert_allclose(out[:, :3], np.broadcast_to(short.channels[:, :3].mean(axis=0), (50, 3)), atol=1e-6)


@pytest.mark.parametrize("spec", ["mssa", "ebf", "kalman"])
def test_a_studio_take_through_gimbal_lock_comes_back_on_its_own_triples(spec, data_root):
    """A Bandai take's engines work on its body view (the Hips under the reference node):
    the triples go back on the take's own once, not swapped again by the view."""
    from workbench.data import find_clip
    from workbench.engine.signal import euler_flips

    take = find_clip("bandai/dance-short/dataset-1_dance-short_normal_001").load().slice(560, 720)
    flips = euler_flips(Observation(take))
    assert flips is not None and flips.other.any()
    out = create(spec).clean(Observation(take)).motion.channels
    cols = (3 + 3 * flips.joints[:, None] + np.arange(3)).ravel()
    step = np.abs(wrap_deg(out[:, cols] - take.channels[:, cols]))
    assert (
        np.median(step) < 2.0 and np.mean(step > 90.0) < 0.01
    )  # no half-turn between the take's triple and the output's
