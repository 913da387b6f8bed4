import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.core import Motion, forward_kinematics, inverse_kinematics
from workbench.core.rotations import wrap_deg
from workbench.metrics import bone_lengths


def test_fk_matches_a_per_joint_reference(walk):
    """FK against a plain per-frame loop written from the BVH definition."""
    from scipy.spatial.transform import Rotation

    sk = walk.skeleton
    f = 100
    P = np.zeros((sk.n_joints, 3))
    R = [None] * sk.n_joints
    for j, p in enumerate(sk.parents):
        local = Rotation.from_euler(sk.rotation_order(j), walk.angles_deg[f, j], degrees=True).as_matrix()
        if p < 0:
            R[j], P[j] = local, walk.root_positions[f] + sk.offsets[j]
        else:
            R[j], P[j] = R[p] @ local, P[p] + R[p] @ sk.offsets[j]
    assert np.allclose(walk.positions[f], P, atol=1e-9)


def test_fk_of_translated_joints_uses_their_translation_for_the_offset(studio_take):
    """The moving Hips under joint_Root sits at its translation in its parent's frame;
    the other joints hang from it by their (folded) offsets."""
    from scipy.spatial.transform import Rotation

    m, sk = studio_take, studio_take.skeleton
    f = 60
    P, R = np.zeros((sk.n_joints, 3)), [None] * sk.n_joints
    for j, p in enumerate(sk.parents):
        local = Rotation.from_euler(sk.rotation_order(j), m.angles_deg[f, j], degrees=True).as_matrix()
        step = m.translations[f, sk.translated.index(j)] if j in sk.translated else sk.offsets[j]
        if p < 0:
            R[j], P[j] = local, m.root_positions[f]
        else:
            R[j], P[j] = R[p] @ local, P[p] + R[p] @ step
    np.testing.assert_allclose(m.positions[f], P, atol=1e-9)
    assert np.linalg.norm(m.positions[f, 1] - m.positions[0, 1]) > 10  # the Hips move


def test_ik_recovers_a_studio_take_and_keeps_its_translations(studio_take, stretchy_take):
    """Translated joints reach their targets: the Hips trajectory, and a stretchy bone's
    changing length, are kept; the angles come back exactly with the true reference."""
    for m in (studio_take, stretchy_take):
        root, ang, trans = inverse_kinematics(m.skeleton, m.positions, m.angles_deg)
        np.testing.assert_allclose(root, m.root_positions, atol=1e-9)
        np.testing.assert_allclose(trans, m.translations, atol=1e-9)
        np.testing.assert_allclose(m.replace(angles_deg=ang).positions, m.positions, atol=1e-6)
        np.testing.assert_allclose(wrap_deg(ang - m.angles_deg), 0, atol=1e-6)


def test_fk_keeps_bone_lengths(walk, kick):
    for m in (walk, kick):
        L = bone_lengths(m.positions, m.skeleton.parents)
        rest = np.linalg.norm(m.skeleton.offsets[1:], axis=1)
        assert np.allclose(L, rest[None], atol=1e-9)


def test_ik_recovers_angles_exactly_with_a_reference(walk, kick):
    for m in (walk, kick):
        root, ang, _ = inverse_kinematics(m.skeleton, m.positions, m.angles_deg)
        assert np.allclose(root, m.root_positions, atol=1e-9)
        assert np.allclose(ang, m.angles_deg, atol=1e-6)


def test_joint_positions_are_the_positions_of_forward_kinematics_bit_for_bit(walk, kick, studio_take):
    """Over several blocks of frames (FK_BLOCK_FRAMES), with translated joints too (the studio take's)."""
    from workbench.core import kinematics
    from workbench.core.kinematics import joint_positions

    assert studio_take.skeleton.translated
    for m in (walk, kick, studio_take):
        long = np.resize(m.angles_deg, (kinematics.FK_BLOCK_FRAMES + 7,) + m.angles_deg.shape[1:])
        root = np.resize(m.root_positions, (len(long), 3))
        translations = np.resize(m.translations, (len(long),) + m.translations.shape[1:])
        P, _ = forward_kinematics(m.skeleton, root, long, translations)
        np.testing.assert_array_equal(joint_positions(m.skeleton, root, long, translations), P)


def test_reference_joints_keep_the_reference_angles(walk):
    """A joint named in reference_joints is not aimed: its angles are the reference's
    (its descendants are aimed from that rotation; the other joints do not change)."""
    hand = walk.skeleton.index("LeftHand")
    ref = walk.angles_deg.copy()
    ref[:, hand] += 7.0
    _, free, _ = inverse_kinematics(walk.skeleton, walk.positions, ref)
    _, kept, _ = inverse_kinematics(walk.skeleton, walk.positions, ref, reference_joints=[hand])
    np.testing.assert_array_equal(kept[:, hand], ref[:, hand])
    assert np.abs(free[:, hand] - ref[:, hand]).max() > 1.0  # aimed at the true fingers
    below = {hand}
    for j, p in enumerate(walk.skeleton.parents):
        if p in below:
            below.add(j)
    others = [j for j in range(walk.skeleton.n_joints) if j not in below]
    np.testing.assert_allclose(kept[:, others], free[:, others], atol=1e-9)


def test_reference_frames_keep_the_reference_there_and_join_the_aim_without_a_jump(walk):
    """A joint kept in some frames has the reference's angles there; in the frames between
    it is aimed, then turned by the reference's departure from the aim, bridged from the
    kept frames around: a constant departure carries over whole, a changing one is
    blended in without a jump. Kept in every frame, it is a reference joint."""
    sk = walk.skeleton
    foot = sk.index("LeftFoot")
    truth = walk.angles_deg
    frames = np.zeros((walk.n_frames, sk.n_joints), bool)
    frames[:50, foot] = frames[100:, foot] = True
    kept = frames[:, foot]
    ref = truth.copy()
    ref[:, foot, 2] += 10.0  # turned off its toe by 10 degrees about its local x
    _, aimed, _ = inverse_kinematics(sk, walk.positions, ref)
    _, out, _ = inverse_kinematics(sk, walk.positions, ref, reference_frames=frames)
    np.testing.assert_allclose(out[kept, foot], ref[kept, foot], atol=1e-6)
    np.testing.assert_allclose(out[~kept, foot], ref[~kept, foot], atol=1e-6)  # the departure, carried over
    assert np.abs(aimed[~kept, foot] - ref[~kept, foot]).max() > 5.0  # the aim alone loses it
    ref[:, foot, 2] += np.linspace(0.0, 10.0, walk.n_frames)  # a departure that grows from 10 to 20 degrees
    _, out, _ = inverse_kinematics(sk, walk.positions, ref, reference_frames=frames)
    np.testing.assert_allclose(out[kept, foot], ref[kept, foot], atol=1e-6)
    step = np.abs(np.diff(out[:, foot] - truth[:, foot], axis=0)).max(axis=1)
    assert step[48:101].max() < 2.0 * step[:48].max()
    everywhere = np.zeros_like(frames)
    everywhere[:, foot] = True
    np.testing.assert_array_equal(
        inverse_kinematics(sk, walk.positions, ref, reference_frames=everywhere)[1],
        inverse_kinematics(sk, walk.positions, ref, reference_joints=[foot])[1],
    )


def test_ik_without_reference_reaches_the_positions(walk, kick):
    for m in (walk, kick):
        root, ang, _ = inverse_kinematics(m.skeleton, m.positions)
        P, _ = forward_kinematics(m.skeleton, root, ang)
        assert np.allclose(P, m.positions, atol=1e-6)


@given(seed=st.integers(0, 10_000), sigma=st.floats(0.01, 2.0))
@settings(max_examples=15, deadline=None)
def test_ik_of_noisy_positions_keeps_bone_lengths_and_gets_close(walk, seed, sigma):
    """Property: for any noise, IK output has the skeleton's bone lengths exactly, and it
    is no farther from the noisy targets than the clean pose hung from the same root
    position is (it is a fit; the root sits at its noisy target, so the clean pose is
    compared from there: from its own root it can be nearer, by up to 8 % at sigma 2)."""
    m = walk.slice(0, 40)
    rng = np.random.default_rng(seed)
    noisy = m.positions + rng.normal(scale=sigma, size=m.positions.shape)
    root, ang, _ = inverse_kinematics(m.skeleton, noisy, m.angles_deg)
    fit = Motion(m.skeleton, m.fps, root, ang)
    L = bone_lengths(fit.positions, m.skeleton.parents)
    assert np.allclose(L, np.linalg.norm(m.skeleton.offsets[1:], axis=1)[None], atol=1e-9)
    err_fit = np.linalg.norm(fit.positions - noisy, axis=2).mean()
    hung = m.positions + (noisy[:, :1] - m.positions[:, :1])
    assert np.allclose(fit.positions[:, 0], noisy[:, 0])
    err_clean = np.linalg.norm(hung - noisy, axis=2).mean()
    assert err_fit <= err_clean


def test_motion_is_read_only_and_channels_round_trip(walk):
    assert not walk.angles_deg.flags.writeable and not walk.positions.flags.writeable
    assert not walk.global_rotations.flags.writeable  # was writable: end sites could be corrupted in place
    assert walk.positions is walk._kinematics[0] and walk.global_rotations is walk._kinematics[1]  # one FK
    again = walk.with_channels(walk.channels)
    assert again.allclose(walk, atol=0)
    assert walk.positions.shape == (walk.n_frames, 31, 3)


def test_motions_share_read_only_arrays_and_a_writable_one_is_copied(walk):
    """A Motion made from another's arrays, and an Observation that marks nothing new,
    share them (a long take is not copied per view); an array someone may still write
    is copied, so writing it later changes no Motion."""
    from workbench.core import Observation

    assert Motion(walk.skeleton, walk.fps, walk.root_positions, walk.angles_deg).angles_deg is walk.angles_deg
    assert Observation(walk).motion is walk
    angles = walk.angles_deg.copy()
    own = Motion(walk.skeleton, walk.fps, walk.root_positions, angles)
    angles[0] = 1e6
    assert own.angles_deg is not angles and own.allclose(walk, atol=0)
    observed = np.ones((walk.n_frames, walk.skeleton.n_joints), bool)
    observed[3, 5] = False
    gapped = Observation(walk, observed)
    assert np.isnan(gapped.motion.angles_deg[3, 5]).all() and not np.isnan(walk.angles_deg).any()


def test_a_joint_near_gimbal_lock_takes_the_twist_whose_euler_angles_are_nearest_the_reference(walk):
    """Aimed at its child, a joint's twist is free: where the reference is measured, IK takes
    the turn whose Euler angles are nearest the reference's. Near gimbal lock the
    reference's own twist (the smallest correction of it, still taken elsewhere) puts the
    angles far off: a left thigh held near its lock with a reference 2 degrees off in
    every channel comes out 5.1 degrees off; with the turn 1.2."""
    sk = walk.skeleton
    j = sk.index("LeftUpLeg")
    truth = walk.angles_deg.copy()
    truth[:, j, 1] = 80.0 + 5.0 * np.sin(np.arange(walk.n_frames) / 20.0)  # ZYX: Y is the middle angle
    ref = truth.copy()
    ref[:, j] += np.random.default_rng(0).normal(scale=2.0, size=ref[:, j].shape)
    positions = walk.replace(angles_deg=truth).positions
    measured = np.ones((walk.n_frames, sk.n_joints), bool)
    _, out, _ = inverse_kinematics(sk, positions, ref, reference_measured=measured)
    _, smallest, _ = inverse_kinematics(sk, positions, ref)  # the reference's own twist

    def error(angles):
        return np.sqrt(np.mean((angles[:, j] - truth[:, j]) ** 2))

    assert error(out) < 0.75 * error(ref) < error(smallest)
    measured[: walk.n_frames // 2] = False  # bridged there: the smallest correction
    _, half, _ = inverse_kinematics(sk, positions, ref, reference_measured=measured)
    np.testing.assert_array_equal(half[: walk.n_frames // 2], smallest[: walk.n_frames // 2])


def test_a_joint_weighs_its_reference_angles_against_its_aim_by_their_variances(walk):
    """With an aim variance, a joint aimed at one direction takes the Euler angles
    likeliest given both measurements: a left thigh held near gimbal lock, its child's
    position 1 cm off and its reference 2 degrees off in each channel, comes out 1.6
    degrees off, against 1.9 for the reference alone and 5.6 for the aim (with the twist
    nearest the reference). A vast aim variance keeps the reference; a small one comes
    nearer the aim and further from the reference."""
    sk = walk.skeleton
    j, child = sk.index("LeftUpLeg"), sk.index("LeftLeg")
    rng = np.random.default_rng(0)
    truth = walk.angles_deg.copy()
    truth[:, j, 1] = 80.0 + 5.0 * np.sin(np.arange(walk.n_frames) / 20.0)  # ZYX: Y is the middle angle
    ref = truth.copy()
    ref[:, j] += rng.normal(scale=2.0, size=ref[:, j].shape)
    positions = walk.replace(angles_deg=truth).positions.copy()
    noise_cm = 1.0
    positions[:, child] += rng.normal(scale=noise_cm / sk.unit_cm, size=positions[:, child].shape)
    measured = np.ones((walk.n_frames, sk.n_joints), bool)
    variances = np.full((sk.n_joints, 3), 4.0)

    def solve(aim_cm2=None):
        aim = None if aim_cm2 is None else np.where(np.arange(sk.n_joints) == j, aim_cm2 / sk.unit_cm**2, np.nan)
        _, angles, _ = inverse_kinematics(
            sk, positions, ref, reference_measured=measured, reference_variance=variances, aim_variance=aim
        )
        return angles

    def rms(angles, of):
        return np.sqrt(np.mean((angles[:, j] - of[:, j]) ** 2))

    def aim_miss_deg(angles):
        reached = walk.replace(angles_deg=angles).positions
        direction, wanted = reached[:, child] - reached[:, j], positions[:, child] - reached[:, j]
        cosine = np.sum(direction * wanted, axis=1) / np.linalg.norm(direction, axis=1) / np.linalg.norm(wanted, axis=1)
        return np.median(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))

    aimed, weighed = solve(), solve(noise_cm**2)
    assert rms(weighed, truth) < 0.9 * rms(ref, truth) < 0.5 * rms(aimed, truth)
    np.testing.assert_allclose(solve(1e12)[:, j], ref[:, j], atol=1e-3)
    surer = solve(0.01 * noise_cm**2)  # the aim 100 times surer
    assert aim_miss_deg(surer) < 0.1 * aim_miss_deg(weighed) and rms(surer, ref) > rms(weighed, ref)
    assert np.isfinite(solve(0.0)).all()  # a descendant that never moves from its joint: aimed at
