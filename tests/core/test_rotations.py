import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from workbench.core import rotations as rot

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]
angles = arrays(np.float64, (5, 3), elements=st.floats(-179.0, 179.0))


@pytest.mark.parametrize("order", ORDERS)
@given(a=angles)
@settings(max_examples=30, deadline=None)
def test_euler_to_matrix_matches_scipy(order, a):
    ours = rot.euler_to_matrix(a, order)
    theirs = Rotation.from_euler(order, a, degrees=True).as_matrix()  # upper case: intrinsic
    assert np.allclose(ours, theirs, atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
@given(a=angles)
@settings(max_examples=30, deadline=None)
def test_matrix_to_euler_inverts(order, a):
    R = rot.euler_to_matrix(a, order)
    back = rot.euler_to_matrix(rot.matrix_to_euler(R, order), order)
    assert np.allclose(back, R, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_matrix_to_euler_matches_scipy_away_from_lock(order):
    rng = np.random.default_rng(0)
    a = rng.uniform(-170, 170, (200, 3))
    a[:, 1] = rng.uniform(-85, 85, 200)
    R = rot.euler_to_matrix(a, order)
    theirs = Rotation.from_matrix(R).as_euler(order, degrees=True)
    assert np.allclose(rot.matrix_to_euler(R, order), theirs, atol=1e-8)
    assert np.allclose(rot.matrix_to_euler(R, order), a, atol=1e-8)


@pytest.mark.parametrize("order", ORDERS)
def test_gimbal_lock_still_gives_the_rotation(order):
    a = np.array([[30.0, 90.0, 40.0], [-20.0, -90.0, 10.0]])
    R = rot.euler_to_matrix(a, order)
    assert np.allclose(rot.euler_to_matrix(rot.matrix_to_euler(R, order), order), R, atol=1e-9)


def test_quaternions_match_scipy():
    R = Rotation.random(500, random_state=1)
    ours = rot.matrix_to_quaternion(R.as_matrix())
    xyzw = R.as_quat()
    theirs = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    theirs *= np.where(theirs[:, :1] < 0, -1, 1)
    assert np.allclose(ours, theirs, atol=1e-10)
    assert np.allclose(rot.quaternion_to_matrix(ours), R.as_matrix(), atol=1e-10)


def test_alternative_and_nearest_euler():
    a = np.array([[10.0, 20.0, 30.0]])
    alt = rot.alternative_euler(a)
    assert np.allclose(rot.euler_to_matrix(alt, "ZYX"), rot.euler_to_matrix(a, "ZYX"))
    ref = np.array([[370.0, 20.0, -330.0]])
    assert np.allclose(rot.nearest_euler(a, ref), [[370.0, 20.0, -330.0]])


@given(x=arrays(np.float64, 50, elements=st.floats(-1e4, 1e4)))
@settings(max_examples=50, deadline=None)
def test_wrap_deg_shifts_by_whole_turns_into_a_half_turn_either_side(x):
    w = rot.wrap_deg(x)
    assert ((w >= -180.0 - 1e-9) & (w < 180.0)).all()
    turns = (x - w) / 360.0
    assert np.allclose(turns, np.round(turns), rtol=0, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
@given(a=angles, shift=arrays(np.float64, (5, 3), elements=st.floats(-500.0, 500.0)))
@settings(max_examples=30, deadline=None)
def test_nearest_euler_is_the_nearest_of_both_triples_and_their_turns(order, a, shift):
    """Against a brute force over both triples shifted by -3..3 whole turns per angle."""
    reference = a + shift
    near = rot.nearest_euler(a, reference)
    assert np.allclose(rot.euler_to_matrix(near, order), rot.euler_to_matrix(a, order), atol=1e-9)
    turns = 360.0 * np.arange(-3, 4)
    best = np.full(len(a), np.inf)
    for triple in (a, rot.alternative_euler(a)):
        steps = triple[..., None] + turns - reference[..., None]  # (5, 3, 7)
        best = np.minimum(best, (np.min(np.abs(steps), axis=-1) ** 2).sum(axis=-1))
    assert np.allclose(((near - reference) ** 2).sum(axis=-1), best, rtol=1e-9, atol=1e-6)


def test_vectors_to_rotation_and_kabsch():
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    R = rot.vectors_to_rotation(a, b)
    mapped = np.einsum("nij,nj->ni", R, a / np.linalg.norm(a, axis=1, keepdims=True))
    assert np.allclose(mapped, b / np.linalg.norm(b, axis=1, keepdims=True), atol=1e-9)
    assert np.allclose(rot.vectors_to_rotation(a, -a) @ a[..., None], -a[..., None], atol=1e-9)
    R_true = Rotation.random(10, random_state=3).as_matrix()
    src = rng.normal(size=(10, 4, 3))
    tgt = np.einsum("nij,nkj->nki", R_true, src)
    assert np.allclose(rot.kabsch(src, tgt), R_true, atol=1e-9)


def test_bad_order_is_a_clear_error():
    with pytest.raises(ValueError, match="permutation"):
        rot.euler_to_matrix(np.zeros(3), "XXY")


@pytest.mark.parametrize("order", ORDERS)
@given(
    a=arrays(np.float64, (5, 3), elements=st.floats(-85.0, 85.0)),
    v=arrays(np.float64, (5, 3), elements=st.floats(-1, 1)),
)
@settings(max_examples=20, deadline=None)
def test_euler_rates_are_the_derivative_of_the_angles_under_a_turn_about_an_axis(order, a, v):
    """The rates of the Euler angles as their rotation turns about an axis of its own
    frame, against a central difference (middle angles away from gimbal lock)."""
    axis = v + np.array([1e-3, 0.0, 0.0])  # never the zero vector
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    h = 1e-6

    def turned(phi):
        turn = Rotation.from_rotvec(phi * axis).as_matrix()
        return rot.nearest_euler(rot.matrix_to_euler(rot.euler_to_matrix(a, order) @ turn, order), a)

    np.testing.assert_allclose(rot.euler_rates(a, order, axis), (turned(h) - turned(-h)) / (2 * h), atol=1e-3)


def test_euler_rates_stay_finite_at_gimbal_lock():
    rates = rot.euler_rates(np.array([[10.0, 90.0, 0.0], [10.0, 89.9, 0.0]]), "ZXY", np.array([0.0, 0.0, 1.0]))
    assert np.isfinite(rates).all() and np.abs(rates[1]).max() > 1e3  # near lock: fast


@pytest.mark.parametrize("order", ORDERS)
@given(a=angles, v=arrays(np.float64, (3,), elements=st.floats(-1, 1)))
@settings(max_examples=20, deadline=None)
def test_euler_axes_turn_a_rotated_vector_as_its_angles_do(order, a, v):
    """d(R v)/d(angle k) is axis_k x R v, per radian, against a central difference; the
    axes are unit vectors, and at gimbal lock the first and the last coincide."""
    axes = rot.euler_axes(a, order)
    h = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        slope = (rot.euler_to_matrix(a + d, order) - rot.euler_to_matrix(a - d, order)) @ v / np.deg2rad(2 * h)
        np.testing.assert_allclose(slope, np.cross(axes[:, k], rot.euler_to_matrix(a, order) @ v), atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(axes, axis=-1), 1.0)
    locked = rot.euler_axes(np.array([30.0, 90.0, -20.0]), order)
    np.testing.assert_allclose(np.abs(locked[0] @ locked[2]), 1.0)


def test_blended_takes_move_each_rotation_along_the_shorter_arc(walk):
    from workbench.core.motion import blended

    a = walk.slice(0, 40)
    rng = np.random.default_rng(0)
    angles = a.angles_deg + rng.uniform(-20.0, 20.0, a.angles_deg.shape)
    angles += 360.0 * (angles < 0)  # triples far from a's, as nearest_euler must undo
    angles[:, 3] = a.angles_deg[:, 3]  # a joint the two agree on
    root = a.root_positions + 10.0
    root[:, 1] = a.root_positions[:, 1]  # and a coordinate
    b = a.replace(angles_deg=angles, root_positions=root)
    mixed = blended(a, b, 0.3)
    np.testing.assert_array_equal(mixed.angles_deg[:, 3], a.angles_deg[:, 3])
    np.testing.assert_array_equal(mixed.root_positions[:, 1], a.root_positions[:, 1])
    np.testing.assert_allclose(mixed.root_positions[:, ::2], a.root_positions[:, ::2] + 3.0)
    assert np.abs(mixed.angles_deg - a.angles_deg).max() < 30.0  # the triples nearest a's, not b's shifted ones
    orders = a.skeleton.rotation_orders
    R = {
        name: [rot.euler_to_matrix(m.angles_deg[:, j], o) for j, o in enumerate(orders)]
        for name, m in (("a", a), ("b", b), ("mix", mixed))
    }
    for j in range(a.skeleton.n_joints):
        whole = rot.rotation_angle_deg(R["a"][j], R["b"][j])
        first, rest = rot.rotation_angle_deg(R["a"][j], R["mix"][j]), rot.rotation_angle_deg(R["mix"][j], R["b"][j])
        np.testing.assert_allclose(first + rest, whole, atol=1e-4)  # on the arc from a to b
        np.testing.assert_allclose(first, 0.3 * whole, atol=0.02 * whole.max() + 1e-4)
    assert blended(a, b, 0.0).allclose(a, atol=1e-9) and blended(a, b, 1.0).allclose(b, atol=1e-9)
    with pytest.raises(ValueError, match="share must be 0 to 1"):
        blended(a, b, 1.5)
    with pytest.raises(ValueError, match="one skeleton, rate and length"):
        blended(a, b.slice(1), 0.3)
