"""EBF, BF and NN (engines/ebf): the adaptive filter's math, streaming == offline,
diagnostics, the bias variant, weights, skeleton checks, a tiny fit and a quality check
with the committed weights. One torch thread; fits are 1-2 epochs on tiny data."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from engines.ebf import BF, EBF, NN  # noqa: E402
from engines.ebf.features import (  # noqa: E402
    RADIUS,
    Layout,
    Normaliser,
    frame_data,
    noise_context,
    root_angular_velocity_dps,
    smoothing_context,
    window_index,
)
from engines.ebf.nets import (  # noqa: E402
    Trig,
    WindowNet,
    circular_mean,
    filter_windows,
    gaussian_filter,
    gaussian_logits,
    local_quadratic_weights,
    offsets_like,
)
from engines.ebf.root import GATES, NARROW_FRAMES, clean_root, filter_limits  # noqa: E402
from workbench import metrics, registry  # noqa: E402
from workbench.core.channels import unwrap_deg  # noqa: E402
from workbench.core.motion import Observation, angle_columns  # noqa: E402
from workbench.corruption import parse_corruption  # noqa: E402
from workbench.engine import EngineError, NotFittedError  # noqa: E402
from workbench.engine.smoothing import measurement_variance  # noqa: E402
from workbench.io import read_bvh  # noqa: E402

torch.set_num_threads(1)
L = 2 * RADIUS + 1


# -- the filter ---------------------------------------------------------------------------
def _windows(B=5, C=4, seed=0):
    g = torch.Generator().manual_seed(seed)
    values = torch.randn(B, L, C, generator=g, dtype=torch.float64) * 10
    valid = torch.ones(B, L, dtype=torch.bool)
    return values, valid


def test_gaussian_weights_renormalised_over_existing_frames():
    values, valid = _windows(B=1, C=1)
    valid[0, :10] = False  # window runs 10 frames off the start of the clip
    sigma = torch.tensor([[4.0]], dtype=torch.float64)
    _, w = filter_windows(gaussian_logits(sigma, offsets_like(values)), values, valid)
    w = w[0, :, 0].numpy()
    d = np.arange(-RADIUS, RADIUS + 1)
    expect = np.exp(-(d**2) / 32.0) * (d >= -5)
    assert np.allclose(w, expect / expect.sum(), atol=1e-12)
    assert np.all(w[:10] == 0) and w.sum() == pytest.approx(1.0)


def test_a_whole_turn_inside_the_window_does_not_move_the_average():
    values, valid = _windows(B=2, C=3)
    turned = values.clone()
    turned[:, 20:] += 360.0  # an unwrapping slip 5 frames after the centre
    logits = gaussian_logits(torch.full((2, 3), 6.0, dtype=torch.float64), offsets_like(values))
    assert torch.allclose(filter_windows(logits, turned, valid)[0], filter_windows(logits, values, valid)[0])


@pytest.mark.parametrize("edge", [False, True])
def test_the_gaussian_filter_is_the_normalised_one(edge):
    values, valid = _windows(B=6, C=5, seed=2)
    values[:, 20:] += 350.0  # far from the centre frame: the circular mean's branch matters
    if edge:
        valid[2, :10] = False  # a window running off the start of the clip
    sigma = torch.tensor([0.01, 0.4, 1.0, 3.0, 8.0, 1e4], dtype=torch.float64)[:, None].expand(6, 5)
    expected, _ = filter_windows(gaussian_logits(sigma, offsets_like(values)), values, valid)
    assert torch.allclose(gaussian_filter(sigma, values, valid), expected, rtol=0, atol=1e-10)


def test_constant_signal_stays_constant():
    values = torch.full((3, L, 2), 37.5, dtype=torch.float64)
    valid = torch.ones(3, L, dtype=torch.bool)
    valid[1, 20:] = False
    sigma = torch.tensor([[0.3, 2.0], [5.0, 50.0], [1.0, 1e3]], dtype=torch.float64)
    out, _ = filter_windows(gaussian_logits(sigma, offsets_like(values)), values, valid)
    assert torch.allclose(out, torch.full((3, 2), 37.5, dtype=torch.float64), atol=1e-12)


def test_huge_sigma_is_window_circular_mean_and_tiny_sigma_is_identity():
    values, valid = _windows()
    valid[2, 25:] = False
    offsets = offsets_like(values)
    huge, _ = filter_windows(gaussian_logits(torch.full((5, 4), 1e6, dtype=torch.float64), offsets), values, valid)
    a = torch.deg2rad(values) * valid[:, :, None]  # invalid frames: angle 0, weight 0
    w = valid[:, :, None].double()
    mean = torch.rad2deg(torch.atan2((w * torch.sin(a)).sum(1), (w * torch.cos(a)).sum(1)))
    assert torch.allclose(huge, mean, atol=1e-6)
    small = values * 0.01  # for small spreads the circular mean is the plain mean
    near, _ = filter_windows(gaussian_logits(torch.full((5, 4), 1e6, dtype=torch.float64), offsets), small, valid)
    plain = (small * valid[:, :, None]).sum(1) / valid.sum(1, keepdim=True)
    assert torch.allclose(near, plain, atol=1e-5)
    tiny, _ = filter_windows(gaussian_logits(torch.full((5, 4), 1e-3, dtype=torch.float64), offsets), values, valid)
    assert torch.allclose(tiny, values[:, RADIUS], atol=1e-12)


def test_local_quadratic_weights_reproduce_a_parabola_and_sum_to_one():
    """Any width, whole windows and windows cut by the clip's start or end; a Gaussian
    mean of the same width misses the parabola's peak by sigma^2 times its curvature."""
    t = torch.arange(-RADIUS, RADIUS + 1, dtype=torch.float64)[None, :, None]
    values = (0.3 + 0.004 * t - 0.001 * t**2).expand(4, L, 3).contiguous()  # degrees: small spreads
    valid = torch.ones(4, L, dtype=torch.bool)
    valid[1, :RADIUS] = False  # the clip's first frame
    valid[2, RADIUS + 3 :] = False  # three frames before its last
    sigma = torch.tensor([[0.7, 3.0, 40.0]], dtype=torch.float64).expand(4, 3)
    weights = local_quadratic_weights(sigma, offsets_like(values), valid)
    assert torch.allclose(weights.sum(dim=1), torch.ones(4, 3, dtype=torch.float64))
    assert (weights[~valid] == 0).all()
    assert torch.allclose(circular_mean(weights, values), torch.full((4, 3), 0.3, dtype=torch.float64), atol=1e-7)
    mean, _ = filter_windows(gaussian_logits(sigma, offsets_like(values)), values, valid)
    assert abs(float(mean[0, 1]) - (0.3 - 0.001 * 3.0**2)) < 1e-4


def test_the_circular_mean_from_the_angles_sines_and_cosines_is_the_same():
    """Inference passes each frame's sines and cosines; the mean is the same as from the
    windows' deviations from their centre: on the centre's branch, whole turns, spreads
    across +-180 degrees and negative weights included."""
    g = torch.Generator().manual_seed(3)
    values = 170.0 + 40.0 * torch.randn(6, L, 5, generator=g, dtype=torch.float64)
    values[1] += 720.0  # an unwrapped channel, two turns up
    values[2, ::2] -= 360.0  # every other frame a turn down
    weights = torch.rand(6, L, 5, generator=g, dtype=torch.float64) - 0.2  # some negative
    weights[:, RADIUS] += L  # the sum stays positive
    direct = circular_mean(weights, values)
    assert torch.allclose(circular_mean(weights, values, Trig.of_degrees(values)), direct, rtol=0, atol=1e-9)
    assert (direct - values[:, RADIUS]).abs().max() < 180.0


def test_local_quadratic_weights_fall_back_to_the_gaussian_where_a_fit_is_ill_posed():
    values, valid = _windows()
    offsets = offsets_like(values)
    sigma = torch.full((5, 4), 1e-3, dtype=torch.float64)  # one frame carries all the weight
    gaussian = torch.softmax(gaussian_logits(sigma, offsets), dim=1)
    assert torch.equal(local_quadratic_weights(sigma, offsets, valid), gaussian)


@pytest.mark.parametrize("encoder, recurrent", [(True, True), (False, True), (False, False)], ids=["ebf", "bf", "nn"])
def test_the_one_window_network_is_the_network(encoder, recurrent):
    """What a stream runs (the B-LSTM's directions paired into two calls, the encoder
    and head in numpy) equals the network on a batch, in float32 and with its core in
    bf16 (there, one bf16 step of the state apart at most)."""
    torch.manual_seed(0)
    net = WindowNet(7, 5, encoder=encoder, recurrent=recurrent, lstm_units=6, dropout=0.5, window=L).eval()
    frames = torch.randn(40, 7)
    with torch.inference_mode():
        codes = net.encode(frames)
        windows = codes.unfold(0, L, 1).permute(0, 2, 1).contiguous()  # (10, L, E)
        one = net.one_window()
        # float32 sums in another order (numpy's BLAS, torch's): 1.2e-6 apart on an AVX2 EPYC
        assert np.abs(np.stack([one.encode(f) for f in frames.numpy()]) - codes.numpy()).max() < 1e-5
        assert np.abs(np.stack([one(w) for w in windows.numpy()]) - net(windows).numpy()).max() < 1e-5
        if recurrent:
            net.run_core_in_bf16()
            one = net.one_window()
            assert np.abs(np.stack([one(w) for w in windows.numpy()]) - net(windows).numpy()).max() < 0.02


def test_window_index_repeats_edges_and_marks_missing_frames():
    idx, valid = window_index(np.array([0, 5, 9]), 10)
    assert idx.shape == (3, L) and idx.min() == 0 and idx.max() == 9
    assert idx[0, RADIUS] == 0 and valid[0, RADIUS : RADIUS + 10].all() and not valid[0, :RADIUS].any()
    assert valid.sum(axis=1).tolist() == [10, 10, 10]


def test_root_angular_velocity_is_heading_invariant(walk):
    from workbench.core.rotations import axis_rotation, euler_to_matrix, matrix_to_euler

    order = walk.skeleton.rotation_order(0)
    v = root_angular_velocity_dps(walk.channels[:, 3:6], order, walk.fps)
    heading = axis_rotation(1, np.deg2rad(70.0))  # about Y, which is up
    turned = matrix_to_euler(heading @ euler_to_matrix(walk.channels[:, 3:6], order), order)
    assert v.shape == (walk.n_frames, 3) and np.all(v[0] == 0)
    assert np.allclose(root_angular_velocity_dps(turned, order, walk.fps), v, atol=1e-6)


def test_root_filter_follows_a_turn_through_gimbal_lock_and_sheds_its_noise():
    """A root turning 180 degrees about the up axis, through the gimbal lock of ZYX's
    middle angle, walking a straight line, its Euler angles as a BVH file stores them
    (the middle one within +-90 degrees, so the others jump by 180 at the lock), with
    about a degree and 0.5 cm of noise: the filter widens to nearly its maximum and
    brings both nearer the clean root (averaging each Euler channel would not: 28
    degrees off at the lock); the clean root itself is left alone."""
    from workbench.core.rotations import axis_rotation, euler_to_matrix, matrix_to_euler, rotation_angle_deg

    F, unit_cm = 240, 2.54
    t = np.arange(F)
    rng = np.random.default_rng(0)
    R_clean = axis_rotation(1, np.deg2rad(np.linspace(0.0, 180.0, F))) @ axis_rotation(
        0, np.deg2rad(5 * np.sin(t / 20))
    )
    R_noisy = R_clean @ euler_to_matrix(rng.normal(0, 0.6, (F, 3)), "ZYX")
    clean = np.concatenate([np.stack([0 * t, 0 * t, 0.5 * t], axis=1), matrix_to_euler(R_clean, "ZYX")], axis=1)
    noisy = np.concatenate(
        [clean[:, :3] + rng.normal(0, 0.5 / unit_cm, (F, 3)), matrix_to_euler(R_noisy, "ZYX")], axis=1
    )
    assert np.abs(np.diff(clean[:, 3])).max() > 170  # the channels jump at the lock
    out, sigma = clean_root(noisy, 5.0, unit_cm, "ZYX", 120.0)

    def errors(X):
        angle = rotation_angle_deg(R_clean, euler_to_matrix(X[:, 3:], "ZYX"))
        return np.linalg.norm(X[:, :3] - clean[:, :3], axis=1).mean() * unit_cm, angle.mean(), angle.max()

    assert np.median(sigma, axis=0).min() > 3.5
    (p_in, r_in, worst_in), (p_out, r_out, worst_out) = errors(noisy), errors(out)
    assert p_out < 0.5 * p_in and r_out < 0.5 * r_in and worst_out < worst_in, (p_in, p_out, r_in, r_out, worst_out)
    kept, sigma_clean = clean_root(clean, 5.0, unit_cm, "ZYX", 120.0)
    assert sigma_clean.max() < NARROW_FRAMES and np.array_equal(kept, clean)


def test_root_filter_limits_follow_the_frame_rate():
    """The position's widest filter keeps its duration, the rotation's gate grows with
    the frame interval; at 120 fps both are as given."""
    widest, gates = filter_limits(5.0, 120.0)
    assert np.array_equal(widest, [5.0, 5.0]) and np.array_equal(gates, GATES)
    widest, gates = filter_limits(5.0, 30.0)
    assert np.allclose(widest, [1.25, 5.0]) and np.allclose(gates, [GATES[0], 4 * GATES[1]])


def test_a_clean_30_fps_root_is_left_where_it_is(ebf_float32, studio_take, data_root):
    """At 30 fps a body moves four times as far between frames as at 120, and the
    120-fps settings read it as noise: they moved this studio take's clean root by 1.08
    cm on average, and a clean CMU run taken at 30 fps by 5.7 cm."""
    out = ebf_float32.clean(Observation(studio_take)).motion
    assert metrics.root_cm(studio_take, out) < 0.05
    run = read_bvh(data_root / "cmu" / "run" / "09_01.bvh").slice(1)
    root = run.channels[::4, :6]
    kept, _ = clean_root(root, 5.0, run.skeleton.unit_cm, run.skeleton.rotation_order(0), 30.0)
    assert np.linalg.norm(kept[:, :3] - root[:, :3], axis=1).mean() * run.skeleton.unit_cm < 0.2


# -- committed weights ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def ebf():
    engine = registry.create("ebf")
    assert engine.skeleton_signature_ is not None, "committed EBF weights are missing"
    return engine


@pytest.fixture(scope="module")
def ebf_float32():
    return registry.create("ebf:bf16=false")


# a clean root; a noisy one; noise that steps channels across +-180 degrees, which offline
# cleaning unwraps robustly (seed 0: a plain unwrap in the stream left a turn behind, 18 degrees)
STREAM_CASES = [("angular:0.5", 3), ("spatial:1", 3), ("angular:2", 0)]


@pytest.mark.parametrize("corruption, seed", STREAM_CASES)
def test_streaming_equals_offline(ebf_float32, walk, corruption, seed):
    obs = parse_corruption(corruption).apply(walk, seed=seed)
    offline = ebf_float32.clean(obs).motion.channels
    stream = ebf_float32.stream(walk.skeleton, walk.fps)
    out, lags = [], []
    for i, frame in enumerate(obs.motion.channels):
        row = stream.push(frame)
        if row is not None:
            lags.append(i - len(out))
            out.append(row)
    out += list(stream.flush())
    assert set(lags) == {RADIUS}
    assert np.abs(np.array(out) - offline).max() < 1e-5


@pytest.mark.parametrize("corruption, seed", STREAM_CASES)
def test_streaming_in_bf16_equals_offline_to_its_rounding(ebf, walk, corruption, seed):
    """Where the CPU runs bf16 natively the B-LSTM's kernels for one window and for a
    batch round differently: up to 0.007 degrees on these cases (float32: 1e-5)."""
    obs = parse_corruption(corruption).apply(walk, seed=seed)
    stream = ebf.stream(walk.skeleton, walk.fps)
    out = [row for frame in obs.motion.channels if (row := stream.push(frame)) is not None]
    out += list(stream.flush())
    assert np.abs(np.array(out) - ebf.clean(obs).motion.channels).max() < 0.02


def test_the_lstm_runs_in_bf16_where_the_cpu_does(ebf, ebf_float32, walk):
    from workbench.engine.torch_support import bf16_is_native

    obs = parse_corruption("angular:0.5").apply(walk, seed=1)
    assert (ebf.net_.bf16_core is not None) == bf16_is_native()
    assert ebf_float32.net_.bf16_core is None
    assert not any("bf16" in key for key in ebf.state_arrays())  # the copy is never saved
    difference = np.abs(ebf.clean(obs).motion.channels - ebf_float32.clean(obs).motion.channels)
    assert difference.max() < 0.5 and np.sqrt((difference**2).mean()) < 0.01


@pytest.mark.parametrize("spec", ["ebf", "ebd"])
def test_offline_cleaning_in_several_network_passes_equals_one(spec, walk, monkeypatch):
    """One pass of all 343 windows gathers them (it reaches the clip's ends); passes of
    100 take the inner ones as views of the frames: the same windows, the same result."""
    engine = registry.create(spec)
    obs = parse_corruption("angular:0.5+gaps:0.01").apply(walk, seed=1)
    monkeypatch.setattr(type(engine), "INFERENCE_CHUNK", 400)
    whole = engine.clean(obs).motion.channels
    monkeypatch.setattr(type(engine), "INFERENCE_CHUNK", 100)
    assert np.abs(engine.clean(obs).motion.channels - whole).max() < 1e-6


def test_a_take_on_a_reference_node_streams_in_its_body_view(ebf_float32, studio_take):
    """A MotionBuilder export (joint_Root carrying the translated Hips, 30 fps) streams as
    offline cleaning sees it, on the studio's weights; the reference node as it came."""
    obs = parse_corruption("angular:0.5").apply(studio_take, seed=2)
    stream = ebf_float32.stream(studio_take.skeleton, studio_take.fps)
    out = [row for frame in obs.motion.channels if (row := stream.push(frame)) is not None]
    out = np.array(out + list(stream.flush()))
    assert np.abs(out - ebf_float32.clean(obs).motion.channels).max() < 1e-4
    assert np.array_equal(out[:, :6], obs.motion.channels[:, :6])  # joint_Root: position and angles


@pytest.mark.parametrize("name", ["bf:bf16=false", "nn"])
def test_the_ablations_stream_as_they_clean(name, walk):
    obs = parse_corruption("angular:0.5").apply(walk, seed=3)
    engine = registry.create(name)
    stream = engine.stream(walk.skeleton, walk.fps)
    out = [row for frame in obs.motion.channels if (row := stream.push(frame)) is not None]
    assert np.abs(np.array(out + list(stream.flush())) - engine.clean(obs).motion.channels).max() < 1e-4


def test_stream_of_a_take_shorter_than_the_window(ebf_float32, walk):
    short = walk.slice(0, 9)
    obs = parse_corruption("spatial:1").apply(short, seed=1)
    stream = ebf_float32.stream(short.skeleton, short.fps)
    assert all(stream.push(f) is None for f in obs.motion.channels)
    assert np.abs(stream.flush() - ebf_float32.clean(obs).motion.channels).max() < 1e-5


@pytest.mark.parametrize("n_frames", [1, 2, 3, 4, 5, 16, 20, 30])
def test_short_takes_stream_as_they_clean(ebf_float32, walk, n_frames):
    """Takes too short for any roughness of the root (under 4 frames), with one or a few,
    and takes that start emitting before the flush: the root's filter sees the same
    window in the stream as offline."""
    obs = parse_corruption("spatial:1").apply(walk.slice(0, n_frames), seed=1)
    stream = ebf_float32.stream(walk.skeleton, walk.fps)
    out = [row for frame in obs.motion.channels if (row := stream.push(frame)) is not None]
    out = np.array(out + list(stream.flush()))
    assert np.abs(out - ebf_float32.clean(obs).motion.channels).max() < 1e-4


def test_stream_refuses_gaps_and_what_is_no_frame(ebf, walk):
    stream = ebf.stream(walk.skeleton, walk.fps)
    frame = walk.channels[0].copy()
    frame[10] = np.nan
    for bad in (frame, {"a": 1}, "frame", frame[:-1], walk.channels[:2, :48]):  # two rows of 48: no frame
        with pytest.raises(EngineError, match="stream frames must be 96 finite channel values"):
            stream.push(bad)


def test_diagnostics_shapes_and_the_root(ebf, walk):
    obs = parse_corruption("angular:0.5+gaps:0.01").apply(walk, seed=0)
    res = ebf.clean(obs)
    sigma = res.diagnostics["filter_sigma_frames"]
    cols = angle_columns(walk.skeleton)
    assert sigma.shape == (walk.n_frames, 3 + 3 * walk.skeleton.n_joints)
    assert np.all(sigma[:, cols] > 0) and np.all((sigma[:, :6] >= 0) & (sigma[:, :6] <= 5.0))
    assert np.isfinite(res.motion.channels).all()
    # the root is clean here: it barely moves (the take's last frames jitter by degrees)
    moved = np.abs(res.motion.channels[:, :6] - obs.motion.channels[:, :6])
    assert np.median(moved) < 1e-3 and moved.max() < 2.0, (np.median(moved), moved.max())
    passed = registry.create("ebf:root_sigma_frames=0").clean(obs)
    assert np.all(passed.diagnostics["filter_sigma_frames"][:, :6] == 0)
    assert np.allclose(passed.motion.channels[:, :6], obs.motion.channels[:, :6], atol=1e-9)
    assert np.allclose(passed.motion.channels[:, cols], res.motion.channels[:, cols])


def test_root_filter_mends_joint_position_noise(ebf, held_out_walk):
    """Under ``spatial`` noise, which reaches the root, ebf used to leave the take worse
    than it came (the paper passes the root through); with the root filter it is better."""
    obs = parse_corruption("spatial:1").apply(held_out_walk, seed=0)
    cleaned = ebf.clean(obs).motion
    passed = registry.create("ebf:root_sigma_frames=0").clean(obs).motion
    noisy = metrics.mpjpe_cm(held_out_walk, obs.motion)
    assert metrics.mpjpe_cm(held_out_walk, cleaned) < noisy < metrics.mpjpe_cm(held_out_walk, passed)
    assert metrics.root_cm(held_out_walk, cleaned) < 0.7 * metrics.root_cm(held_out_walk, obs.motion)


def _reference_filter(X: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Gaussian filter (weighted circular mean) of angles X (F, C) in degrees with
    per-sample sigma (F, C) over +/-RADIUS frames, weights renormalised over the frames
    that exist (plain numpy, loops)."""
    F = X.shape[0]
    out = np.empty_like(X)
    for t in range(F):
        lo, hi = max(0, t - RADIUS), min(F, t + RADIUS + 1)
        d = np.arange(lo, hi) - t
        w = np.exp(-(d[:, None] ** 2) / (2 * sigma[t] ** 2))
        a = np.deg2rad(X[lo:hi] - X[t])  # the weighted circular mean, on frame t's branch
        out[t] = X[t] + np.rad2deg(np.arctan2((w * np.sin(a)).sum(0), (w * np.cos(a)).sum(0)))
    return out


def test_output_is_the_gaussian_filter_of_its_diagnostic_sigma(ebf, walk):
    obs = parse_corruption("angular:0.5").apply(walk.slice(0, 80), seed=2)
    res = ebf.clean(obs)
    cols = angle_columns(walk.skeleton)
    X = unwrap_deg(obs.motion.channels[:, 3:])[:, cols - 3]
    expect = _reference_filter(X, res.diagnostics["filter_sigma_frames"][:, cols])
    got = res.motion.channels[:, cols]
    assert np.abs((got - expect + 180) % 360 - 180).max() < 1e-6


def test_bias_variant_subtracts_its_bias(walk):
    engine = registry.create("ebf:bias=true")
    assert engine.default_weights_dir().name == "ebf-bias" and engine.skeleton_signature_ is not None
    obs = parse_corruption("bias:0.5").apply(walk.slice(0, 80), seed=2)
    res = engine.clean(obs)
    cols = angle_columns(walk.skeleton)
    bias = res.diagnostics["bias"]
    assert bias.shape == res.diagnostics["filter_sigma_frames"].shape and np.all(bias[:, :6] == 0)
    assert np.abs(bias[:, cols]).max() > 0.1
    X = unwrap_deg(obs.motion.channels[:, 3:])[:, cols - 3]
    expect = _reference_filter(X, res.diagnostics["filter_sigma_frames"][:, cols]) - bias[:, cols]
    assert np.abs((res.motion.channels[:, cols] - expect + 180) % 360 - 180).max() < 1e-6


def test_refuses_another_skeleton_naming_the_ones_it_has_weights_for(ebf, kick, walk, tmp_path):
    obs = Observation(kick.slice(0, 60))
    with pytest.raises(EngineError, match=r"it has weights for 21 joints .* \(bandai\) and 31 joints .* \(cmu\)"):
        ebf.clean(obs)
    with pytest.raises(EngineError, match="skeleton"):
        ebf.stream(kick.skeleton, kick.fps)
    from workbench.io.bvh import format_bvh

    text = format_bvh(walk.slice(0, 60))  # the CMU joints, the first arm joint turning in another order
    at = text.index("JOINT LeftArm")
    channels = text.index("Zrotation Yrotation Xrotation", at)
    (tmp_path / "t.bvh").write_text(text[:channels] + "Xrotation Yrotation Zrotation" + text[channels + 29 :])
    with pytest.raises(EngineError, match="the joints of its cmu weights with other channels or rotation orders"):
        ebf.clean(Observation(read_bvh(tmp_path / "t.bvh")))
    (tmp_path / "r.bvh").write_text(text.replace("JOINT LeftArm", "JOINT LinkerArm"))  # one joint renamed
    with pytest.raises(EngineError, match="the joints of its cmu weights but 'LinkerArm' where they have 'LeftArm';"):
        ebf.clean(Observation(read_bvh(tmp_path / "r.bvh")))
    from workbench.engine.base import _naming_difference

    known = {"Hips<-1>;Spine<0>;Head<1>": "renamed", "Hips<-1>;Spine<0>;LeftArm<1>": "same"}  # the same joints first
    assert "its same weights with other channels" in _naming_difference(["Hips", "Spine", "LeftArm"], known)


def test_ebf_beats_gaussian_on_a_held_out_walk(ebf, held_out_walk):
    gaussian = registry.create("gaussian")
    errs = {"ebf": [], "gaussian": []}
    for seed in range(2):
        obs = parse_corruption("angular:0.5").apply(held_out_walk, seed)
        errs["ebf"].append(metrics.rms_angle_deg(held_out_walk, ebf.clean(obs).motion))
        errs["gaussian"].append(metrics.rms_angle_deg(held_out_walk, gaussian.clean(obs).motion))
    assert np.mean(errs["ebf"]) < 0.8 * np.mean(errs["gaussian"]), errs


# -- fitting, weights, parameters ---------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny(clips):
    from workbench.data import select

    return [c.load().slice(0, 120) for c in select(clips, "train", dataset="cmu")[:2]]


def test_unfitted_raises(walk):
    with pytest.raises(NotFittedError):
        EBF().clean(Observation(walk.slice(0, 40)))
    with pytest.raises(NotFittedError):
        EBF().stream(walk.skeleton, walk.fps)
    with pytest.raises(NotFittedError, match=r"workbench train 'ebf:free=True'"):  # the variant to train
        registry.create("ebf:free=true").clean(Observation(walk.slice(0, 40)))


def test_tiny_fit_learns_and_round_trips_through_save_and_load(tiny, tmp_path):
    engine = EBF(EBF.Params(epochs=3, lstm_units=8, batch_windows=64, seed=1)).fit(tiny)
    history = engine.loss_history_
    assert history.shape == (3,) and np.isfinite(history).all() and history[-1] < history[0]
    obs = parse_corruption("angular:0.5").apply(tiny[0], seed=0)
    before = engine.clean(obs).motion.channels
    engine.save(tmp_path)
    again = EBF(EBF.Params(epochs=1, lstm_units=8)).load(tmp_path)
    assert np.array_equal(again.clean(obs).motion.channels, before)
    assert np.array_equal(EBF().load(tmp_path).clean(obs).motion.channels, before)  # its size comes along
    with pytest.raises(EngineError, match="lstm_units"):
        EBF(EBF.Params(lstm_units=32)).load(tmp_path)  # a network of another size than asked for


def test_two_thread_fits_are_repeatable_and_restore_the_thread_count(tiny, monkeypatch):
    """Two threads, as ``workbench train`` uses here. (Without torch's deterministic
    algorithms, full-size training differed from run to run; at this size it did not,
    so :func:`workbench.engine.torch_support.reproducible_training` has its own test.)"""
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    params = EBF.Params(epochs=1, lstm_units=16, batch_windows=64, seed=3)
    threads = torch.get_num_threads()
    first, second = (EBF(params).fit(tiny).state_arrays() for _ in range(2))
    assert first.keys() == second.keys()
    assert all(np.array_equal(first[k], second[k]) for k in first)
    assert torch.get_num_threads() == threads


@pytest.mark.parametrize("cls,options", [(EBF, {"free": True, "bias": True}), (BF, {}), (NN, {})])
def test_variants_fit_and_clean(cls, options, tiny):
    params = dict(epochs=1, batch_windows=64, **options)
    if cls is not NN:
        params["lstm_units"] = 8
    engine = cls(cls.Params(**params)).fit(tiny[:1])
    res = engine.clean(parse_corruption("angular:0.5").apply(tiny[1], seed=0))
    assert np.isfinite(res.motion.channels).all()
    assert set(res.diagnostics) == ({"filter_sigma_frames", "bias"} if options else {"filter_sigma_frames"})
    sigma = res.diagnostics["filter_sigma_frames"][:, angle_columns(tiny[1].skeleton)]
    assert np.isfinite(sigma).all() and np.all(sigma >= 0)


def test_each_variant_has_its_own_weights_folder():
    assert registry.create("ebf", pretrained=False).default_weights_dir().name == "ebf"
    assert registry.create("ebf:bias=true", pretrained=False).default_weights_dir().name == "ebf-bias"
    assert registry.create("ebf:free=true,bias=true", pretrained=False).variant == "ebf-bias-free"
    assert registry.create("ebf:positions=true", pretrained=False).default_weights_dir().name == "ebf-positions"
    assert registry.create("ebf:epochs=3", pretrained=False).default_weights_dir().name == "ebf"
    assert registry.create("bf", pretrained=False).default_weights_dir().name == "bf"
    with pytest.raises(EngineError):
        registry.create("ebf:lstm_units=0")


def test_noise_context_is_the_takes_own_noise_std_in_training_stds(walk):
    """White noise of a known std on every channel: the context recovers it (the walk at
    120 fps is smooth enough for the second differences), the same on every frame and
    in the frame data's last C columns; gaps do not change it much."""
    layout = Layout.of(walk.skeleton)
    norm = Normaliser.fit([walk], layout)
    C = layout.n_channels
    sigma = 0.5 * norm.angle_std
    noisy = walk.channels.copy()
    noisy[:, layout.columns] += np.random.default_rng(0).normal(0.0, 1.0, (walk.n_frames, C)) * sigma
    obs = Observation(walk.with_channels(noisy))
    values = frame_data(obs, layout, norm, with_mask=False).values
    context = noise_context(values, np.ones_like(values, bool), norm)
    assert np.median(np.abs(context - np.log(0.5))) < 0.1 and np.abs(context - np.log(0.5)).max() < 0.25
    data = frame_data(obs, layout, norm, with_mask=False, with_noise=True)
    assert data.inputs.shape == (walk.n_frames, 2 * C + 3)
    assert np.allclose(data.inputs[:, -C:], context[None, :], atol=1e-6)
    both = frame_data(obs, layout, norm, with_mask=False, with_noise=True, with_smoothing=True).inputs
    width = smoothing_context(
        values, np.ones_like(values, bool), measurement_variance(values, np.ones_like(values, bool))
    )
    assert both.shape == (walk.n_frames, 3 * C + 3) and np.array_equal(both[:, : 2 * C + 3], data.inputs)
    assert np.allclose(both[:, -C:], width[None, :], atol=1e-6)
    holed = parse_corruption("gaps:0.05").apply(walk.with_channels(noisy), seed=0)
    with_gaps = frame_data(holed, layout, norm, with_mask=False, with_noise=True).inputs[0, -C:]
    assert np.median(np.abs(with_gaps - context)) < 0.1


def test_smoothing_context_widens_with_the_noise_and_narrows_with_the_motion():
    """The log width kalman's smoother would take: wider under more noise, narrower for
    faster motion, each channel on its own; the frame data carries it after the noise."""
    t = np.arange(600.0)
    rng = np.random.default_rng(0)
    slow, fast = np.sin(2 * np.pi * t / 200), np.sin(2 * np.pi * t / 20)
    values = 10.0 * np.stack([slow, slow, fast], axis=1) + rng.normal(0.0, 1.0, (600, 3)) * [0.5, 2.0, 0.5]
    variance = np.array([0.25, 4.0, 0.25])
    width = smoothing_context(values, np.ones_like(values, bool), variance)
    assert width.shape == (3,) and width[1] > width[0] > width[2]
    assert np.exp(width[2]) < 3.0 < np.exp(width[0])  # frames


def test_quadratic_variant_fits_and_cleans_and_is_not_a_free_filter(tiny):
    engine = registry.create("ebf:quadratic=true,epochs=1,lstm_units=8,batch_windows=64", pretrained=False)
    engine.fit(tiny[:1])
    res = engine.clean(parse_corruption("angular:0.5").apply(tiny[1], seed=0))
    assert np.isfinite(res.motion.channels).all() and set(res.diagnostics) == {"filter_sigma_frames"}
    with pytest.raises(EngineError, match="choose one"):
        registry.create("ebf:quadratic=true,free=true", pretrained=False)


@pytest.mark.parametrize("context", ["noise_context", "smoothing_context"])
def test_take_context_variants_fit_clean_and_refuse_to_stream(tiny, context):
    engine = registry.create(f"ebf:{context}=true,epochs=1,lstm_units=8,batch_windows=64", pretrained=False)
    engine.fit(tiny[:1])
    assert engine.variant == f"ebf-lstm_units8-{context}"
    res = engine.clean(parse_corruption("angular:0.5").apply(tiny[1], seed=0))
    assert np.isfinite(res.motion.channels).all()
    with pytest.raises(EngineError, match="cannot stream"):
        engine.stream(tiny[1].skeleton, tiny[1].fps)


def test_step_inputs_do_not_depend_on_the_pose_and_stream_as_they_clean(tiny, tmp_path, monkeypatch):
    """The angle inputs are steps from the frame before in training step stds (0 on the
    first frame; across the blocks frame_data works in too), unchanged when a channel is
    shifted by a constant; the steps' stds travel with the weights (weights without them
    are refused), and a stream computes the same steps offline cleaning does."""
    from engines.ebf import features

    monkeypatch.setattr(features, "FEATURE_BLOCK", 7)
    engine = registry.create("ebf:step_inputs=true,epochs=1,lstm_units=8,batch_windows=64,bf16=false", pretrained=False)
    engine.fit(tiny[:1])
    assert engine.variant == "ebf-lstm_units8-step_inputs"
    obs = parse_corruption("angular:0.5").apply(tiny[1], seed=0)
    layout = Layout.of(obs.skeleton)
    norm = engine.norm_
    inputs = engine._frame_data(obs).inputs[:, : layout.n_channels]
    values = unwrap_deg(obs.motion.channels[:, layout.columns])
    expected = np.clip(np.diff(values, axis=0, prepend=values[:1]) / norm.step_std, -20, 20)
    assert np.allclose(inputs, expected, atol=1e-4) and not inputs[0].any()
    shifted = obs.motion.channels.copy()
    shifted[:, layout.columns[3]] += 30.0
    moved = engine._frame_data(Observation(obs.motion.with_channels(shifted))).inputs
    assert np.allclose(moved[:, : layout.n_channels], inputs, atol=1e-5)
    offline = engine.clean(obs).motion.channels
    engine.save(tmp_path)
    again = EBF().load(tmp_path)
    assert np.array_equal(again.norm_.step_std, norm.step_std)
    assert np.array_equal(again.clean(obs).motion.channels, offline)
    arrays = engine.state_arrays()
    with pytest.raises(EngineError, match="step_inputs=True: they hold no steps' stds"):
        registry.create("ebf:step_inputs=true,lstm_units=8", pretrained=False).load_state_arrays(
            {k: v for k, v in arrays.items() if k != "norm_step_std"}, {}
        )
    with pytest.raises(EngineError, match="step_inputs=False"):
        registry.create("ebf:lstm_units=8", pretrained=False).load_state_arrays(arrays, {})
    stream = again.stream(obs.skeleton, obs.motion.fps)
    out = [row for frame in obs.motion.channels if (row := stream.push(frame)) is not None]
    out += list(stream.flush())
    assert np.abs(np.array(out) - offline).max() < 1e-5


def test_positions_variant_also_trains_on_joint_position_noise(tiny):
    """Every clip gets a fourth training copy, with spatial noise: it moves the root too,
    which angular noise leaves alone."""
    plain = registry.create("ebf:time_scale_pct=0", pretrained=False)._training_pairs(tiny, 0)
    pairs = registry.create("ebf:positions=true,time_scale_pct=0", pretrained=False)._training_pairs(tiny, 0)
    assert len(plain) == 3 * len(tiny) and len(pairs) == 4 * len(tiny)
    root_moved = [not np.allclose(obs.motion.channels[:, :6], truth.channels[:, :6]) for obs, truth in pairs]
    assert root_moved == [False, False, False, True] * len(tiny)


@pytest.mark.parametrize("name", ["bf", "nn", "ebf:positions=true"])
def test_ablations_have_committed_weights(name, walk):
    engine = registry.create(name)
    res = engine.clean(parse_corruption("angular:0.5").apply(walk.slice(0, 60), seed=0))
    assert np.isfinite(res.motion.channels).all()


@pytest.mark.parametrize(
    "name",
    [
        "ebf:quadratic=true",
        "ebf:quadratic=true,noise_context=true",
        "ebf:quadratic=true,smoothing_context=true",
        "ebf:quadratic=true,smoothing_context=true,step_inputs=true",
    ],
)
def test_studio_variants_have_bandai_weights_only(name, studio_take, walk):
    engine = registry.create(name)
    res = engine.clean(parse_corruption("angular:0.5").apply(studio_take.slice(0, 60), seed=0))
    assert np.isfinite(res.motion.channels).all()
    assert engine.weights_used_.endswith(f"{engine.variant}/bandai")
    with pytest.raises(EngineError, match="train"):
        registry.create(name).clean(parse_corruption("angular:0.5").apply(walk.slice(0, 60), seed=0))


def test_the_context_variant_has_weights_for_both_skeletons(studio_take, walk):
    engine = registry.create("ebf:quadratic=true,noise_context=true,smoothing_context=true")
    for take, dataset in ((studio_take, "bandai"), (walk, "cmu")):
        res = engine.clean(parse_corruption("angular:0.5").apply(take.slice(0, 60), seed=0))
        assert np.isfinite(res.motion.channels).all()
        assert engine.weights_used_.endswith(f"{engine.variant}/{dataset}")


def test_a_stream_picks_the_weights_of_its_skeleton_and_runs_at_their_rate(walk, studio_take):
    """A fresh engine starts on one committed set (the first folder by name); a stream of
    CMU takes switches to the CMU weights, and a stream at another rate is refused."""
    engine = registry.create("ebf")
    engine.clean(Observation(studio_take.slice(0, 40)))  # now on the Bandai weights
    stream = engine.stream(walk.skeleton, walk.fps)
    assert engine.skeleton_signature_ == walk.skeleton.signature() and stream.push(walk.channels[0]) is None
    with pytest.raises(EngineError, match="streams takes at the 120 fps its weights run at, not 60"):
        engine.stream(walk.skeleton, 60.0)
    with pytest.raises(EngineError, match="not nan"):
        engine.stream(walk.skeleton, float("nan"))


def test_a_stream_keeps_its_weights_when_its_engine_cleans_another_skeleton(walk, studio_take):
    engine = registry.create("ebf:bf16=false")
    stream = engine.stream(walk.skeleton, walk.fps)
    out = [stream.push(f) for f in walk.channels[:20]]
    engine.clean(Observation(studio_take.slice(0, 40)))  # the engine now on the Bandai weights
    out += [stream.push(f) for f in walk.channels[20:]]
    out = np.array([row for row in out if row is not None] + list(stream.flush()))
    assert np.abs(out - registry.create("ebf:bf16=false").clean(Observation(walk)).motion.channels).max() < 1e-5
