"""Batched SE(3) helpers: inverse, composition, skew, angles, screw parameters."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry import se3
from strategies import transforms


def test_invert_is_inverse_for_stacks(rng):
    T = se3.make_transform(se3.random_rotations(50, rng), rng.normal(size=(50, 3)))
    I = se3.invert(T) @ T
    assert np.abs(I - np.eye(4)).max() < 1e-14
    assert np.abs(se3.invert(T) - np.linalg.inv(T)).max() < 1e-13


def test_perturb_rotates_about_the_reference_axes_and_shifts_the_origin(rng):
    T = se3.make_transform(se3.random_rotations(4, rng), rng.normal(size=(4, 3)))
    rotvec, shift = 0.1 * rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
    moved = se3.perturb(T, rotvec, shift)
    dR = Rotation.from_rotvec(rotvec).as_matrix()
    assert np.allclose(moved[:, :3, :3], dR @ T[:, :3, :3]) and np.allclose(moved[:, :3, 3], T[:, :3, 3] + shift)
    assert np.allclose(se3.perturb(T[0], rotvec[0], shift[0]), moved[0])  # one pose as a stack of one
    assert np.array_equal(se3.perturb(T, np.zeros(3), np.zeros(3)), T)


def test_compose_matches_matmul_and_broadcasts(rng):
    A = se3.make_transform(se3.random_rotations(5, rng), rng.normal(size=(5, 3)))
    B = se3.make_transform(se3.random_rotations(1, rng)[0], rng.normal(size=3))
    assert np.allclose(se3.compose(A, B, A), A @ B @ A)
    with pytest.raises(ValueError):
        se3.compose()


def test_skew_is_cross_product(rng):
    v, w = rng.normal(size=(2, 10, 3))
    assert np.allclose(np.einsum("nij,nj->ni", se3.skew(v), w), np.cross(v, w))
    S = se3.skew(v)
    assert np.allclose(S, -np.swapaxes(S, -1, -2))


@pytest.mark.parametrize("angle", [1e-12, 1e-9, 1e-6, 0.3, np.pi / 2, np.pi - 1e-6, np.pi])
def test_rotation_angle_is_accurate_at_both_ends(angle):
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    R = Rotation.from_rotvec(angle * axis).as_matrix()
    # arccos((trace-1)/2) would return 0 for 1e-9 (and ~1e-8 noise): the quaternion form must not
    assert se3.rotation_angle(R) == pytest.approx(angle, rel=1e-6, abs=1e-15)


def test_rotation_error_and_translation_error(rng):
    R = se3.random_rotations(1, rng)[0]
    T1 = se3.make_transform(R, [0.1, 0.2, 0.3])
    dR = Rotation.from_rotvec([0.0, 0.0, 1e-10]).as_matrix()
    T2 = se3.make_transform(R @ dR, [0.1, 0.2, 0.3 + 1e-3])
    assert rotation_error(T2, T1) == pytest.approx(1e-10, rel=1e-5)
    assert translation_error(T2, T1) == pytest.approx(1e-3)
    assert rotation_error(T1, T1) < 1e-15


@settings(max_examples=200, deadline=None)
@given(transforms())
def test_screw_parameters_rebuild_the_transform(T):
    l, m, theta, d = se3.screw_parameters(T)
    if theta < 1e-6 or theta > np.pi - 1e-6:
        return  # screw axis undefined at 0, ambiguous at pi
    assert abs(np.linalg.norm(l) - 1) < 1e-12
    assert abs(l @ m) < 1e-9  # Plücker condition
    # Rebuild: rotate by theta about the line through c = l x m, then translate d along l.
    c = np.cross(l, m)
    R = Rotation.from_rotvec(theta * l).as_matrix()
    t = (np.eye(3) - R) @ c + d * l
    assert np.allclose(R, T[:3, :3], atol=1e-9)
    assert np.allclose(t, T[:3, 3], atol=1e-9)


def test_screw_parameters_of_pure_translation():
    T = se3.make_transform(np.eye(3), [0.0, 3.0, 4.0])
    l, m, theta, d = se3.screw_parameters(T)
    assert theta == 0.0 and d == pytest.approx(5.0)
    assert np.allclose(l, [0.0, 0.6, 0.8]) and np.allclose(m, 0.0)


def test_screw_parameters_invariant_under_conjugation(rng):
    # theta and d of B = X^-1 A X equal those of A: the basis of the screw-congruence check
    A = se3.make_transform(se3.random_rotations(20, rng), rng.normal(size=(20, 3)))
    X = se3.make_transform(se3.random_rotations(1, rng)[0], rng.normal(size=3))
    B = se3.invert(X) @ A @ X
    _, _, th_a, d_a = se3.screw_parameters(A)
    _, _, th_b, d_b = se3.screw_parameters(B)
    assert np.allclose(th_a, th_b, atol=1e-12) and np.allclose(d_a, d_b, atol=1e-12)


def test_rotvec_translation_round_trip(rng):
    rv = rng.normal(size=(7, 3))
    rv *= (np.pi * 0.9 / np.linalg.norm(rv, axis=1))[:, None] * rng.uniform(0, 1, (7, 1))
    t = rng.normal(size=(7, 3))
    rv2, t2 = se3.to_rotvec_translation(se3.from_rotvec_translation(rv, t))
    assert np.allclose(rv, rv2) and np.allclose(t, t2)


def test_orthonormality_error_detects_scaling():
    assert se3.orthonormality_error(np.eye(3)) == 0.0
    assert se3.orthonormality_error(1.001 * np.eye(3)) == pytest.approx(0.002001)
