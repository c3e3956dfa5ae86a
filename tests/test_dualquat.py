"""DualQuaternion: the thesis's §4.1.1 API and the algebra of appendix B, as properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from scipy.spatial.transform import Rotation

from handeye import DualQuaternion
from handeye.geometry import dualquat as dqm
from handeye.geometry.se3 import make_transform, random_rotations, screw_parameters
from strategies import transforms, unit_quaternions

PROPS = settings(max_examples=150, deadline=None)


def same_transform(dq1: DualQuaternion, dq2: DualQuaternion, atol: float = 1e-9) -> bool:
    """q and -q are the same transform."""
    a, b = dq1.as_array(), dq2.as_array()
    return np.allclose(a, b, atol=atol) or np.allclose(a, -b, atol=atol)


@PROPS
@given(transforms())
def test_matrix_round_trip(T):
    dq = DualQuaternion.from_matrix(T)
    assert dq.is_unit(1e-12)
    assert dq.real[0] >= 0  # the thesis's sign convention (§2.2.3)
    assert np.allclose(dq.to_matrix(), T, atol=1e-12)


@PROPS
@given(transforms(), transforms())
def test_product_is_matrix_product(T1, T2):
    dq = DualQuaternion.from_matrix(T1) * DualQuaternion.from_matrix(T2)
    assert np.allclose(dq.to_matrix(), T1 @ T2, atol=1e-12)


@PROPS
@given(transforms())
def test_exp_log_round_trip(T):
    dq = DualQuaternion.from_matrix(T)
    lg = dq.log()
    assert abs(lg.real[0]) < 1e-15 and abs(lg.dual[0]) < 1e-15  # log is a pure dual quaternion
    assert same_transform(lg.exp(), dq, atol=1e-10)


@PROPS
@given(transforms())
def test_log_is_half_dual_angle_times_screw_axis(T):
    l, m, theta, d = screw_parameters(T)
    if theta < 1e-6 or theta > np.pi - 1e-6:
        return
    lg = DualQuaternion.from_matrix(T).log()
    assert np.allclose(lg.real[1:], 0.5 * theta * l, atol=1e-10)
    assert np.allclose(lg.dual[1:], 0.5 * (d * l + theta * m), atol=1e-9)


@PROPS
@given(transforms())
def test_screw_round_trip(T):
    l, m, theta, d = screw_parameters(T)
    if theta > np.pi - 1e-6:
        return
    dq = DualQuaternion.from_screw(theta, d, l, m)
    assert dq.is_unit(1e-12)
    assert np.allclose(dq.to_matrix(), T, atol=1e-9)
    theta2, d2, l2, m2 = dq.screw()
    if theta > 1e-6:
        assert theta2 == pytest.approx(theta, abs=1e-9) and d2 == pytest.approx(d, abs=1e-9)
        assert np.allclose(l2, l, atol=1e-9) and np.allclose(m2, m, atol=1e-8)


@PROPS
@given(transforms())
def test_inverse_and_conjugate(T):
    dq = DualQuaternion.from_matrix(T)
    assert np.allclose(dq.inverse().to_matrix(), np.linalg.inv(T), atol=1e-12)
    assert np.allclose(dq.conjugate().as_array(), dq.inverse().as_array(), atol=1e-12)
    assert same_transform(dq * dq.inverse(), DualQuaternion.identity(), atol=1e-12)


@PROPS
@given(transforms(), unit_quaternions())
def test_transform_point_and_vector(T, q):
    dq = DualQuaternion.from_matrix(T)
    p = q[1:] * 3.0
    assert np.allclose(dq.transform_point(p), T[:3, :3] @ p + T[:3, 3], atol=1e-12)
    assert np.allclose(dq.transform_vector(p), T[:3, :3] @ p, atol=1e-12)
    assert np.allclose(dq.rotation(), T[:3, :3], atol=1e-12)
    assert np.allclose(dq.translation(), T[:3, 3], atol=1e-12)
    assert np.allclose(dq.translation_quaternion(), np.r_[0.0, T[:3, 3]], atol=1e-12)


@PROPS
@given(transforms(), unit_quaternions())
def test_normalize_restores_unit_conditions(T, q):
    scale = 0.5 + abs(q[0])
    # a non-unit dual quaternion: scaled by the dual number scale + eps * 0.3
    dq = DualQuaternion.from_matrix(T)
    raw = DualQuaternion(scale * dq.real, scale * dq.dual + 0.3 * dq.real)
    assert not raw.is_unit()
    n, nd = raw.norm()
    assert n == pytest.approx(scale) and nd == pytest.approx(0.3)
    assert raw.normalized().is_unit(1e-12)
    assert np.allclose(raw.normalized().to_matrix(), T, atol=1e-10)
    raw.normalize()
    assert raw.is_unit(1e-12)


def test_constructors():
    dq = DualQuaternion.from_rotation_translation([2.0, 0.0, 0.0, 0.0], [0.1, 0.2, 0.3])
    assert np.allclose(dq.to_matrix(), make_transform(np.eye(3), [0.1, 0.2, 0.3]))
    assert np.allclose(DualQuaternion.identity().to_matrix(), np.eye(4))
    assert np.all(DualQuaternion.zeros().as_array() == 0.0)
    dq2 = DualQuaternion.from_array(dq.as_array())
    assert np.array_equal(dq2.as_array(), dq.as_array())
    with pytest.raises(ValueError):
        DualQuaternion([1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        DualQuaternion.from_rotation_translation([0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    with pytest.raises(ZeroDivisionError):
        DualQuaternion.zeros().inverse()


def test_quaternion_helpers_match_scipy(rng):
    R = Rotation.from_matrix(random_rotations(20, rng))
    q = dqm.quat_from_matrix(R.as_matrix())
    assert np.all(q[:, 0] >= 0)
    assert np.allclose(dqm.quat_to_matrix(q), R.as_matrix())
    p = dqm.quat_from_matrix(Rotation.from_matrix(random_rotations(20, rng)).as_matrix())
    prod = dqm.qmul(p, q)
    ref = (Rotation.from_quat(p, scalar_first=True) * Rotation.from_quat(q, scalar_first=True)).as_quat(scalar_first=True)
    assert np.allclose(np.abs(np.sum(prod * ref, axis=1)), 1.0)
    assert np.allclose(dqm.qmul_matrix(p) @ q[..., None], prod[..., None])


def test_batched_pair_products_match_direct(rng):
    T = make_transform(random_rotations(30, rng), rng.normal(size=(30, 3)))
    dq = dqm.dq_from_matrix(T)
    i, j = np.triu_indices(30, 1)
    direct = dqm.dq_mul(dqm.dq_conj(dq)[j], dq[i])
    assert np.allclose(dqm.dq_mul_pairs(dqm.dq_conj(dq), dq, j, i), direct, atol=1e-15)
    few = np.array([0, 5]), np.array([3, 4])  # few pairs: the direct branch
    assert np.allclose(dqm.dq_mul_pairs(dq, dq, *few), dqm.dq_mul(dq[few[0]], dq[few[1]]))
    assert np.allclose(dqm.dq_to_matrix(direct), np.linalg.inv(T[j]) @ T[i], atol=1e-12)
