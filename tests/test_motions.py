"""relative_motions: DESIGN §2 conventions for both setups, pair strategies, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import handeye
from handeye import InputMismatchError, PoseFormatError, relative_motions
from handeye.frames.motions import MotionSet, pair_indices, screw_congruence
from handeye.geometry.se3 import invert
from handeye.simulate import random_scene


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
@pytest.mark.parametrize("pairs", ["all", "consecutive"])
def test_ax_equals_xb_with_ground_truth(setup, pairs):
    scene = random_scene(12, setup, rng=3)
    A, B = relative_motions(scene.flange2base, scene.target2cam, setup=setup, pairs=pairs)
    assert len(A) == (66 if pairs == "all" else 11)
    assert np.abs(A @ scene.X - scene.X @ B).max() < 1e-12


def test_formulas_of_design_section_2():
    scene = random_scene(4, "eye_in_hand", rng=0)
    F, C = scene.flange2base, scene.target2cam
    A, B = relative_motions(F, C, "eye_in_hand", pairs=[[0, 2]])
    assert np.allclose(A[0], np.linalg.inv(F[2]) @ F[0]) and np.allclose(B[0], C[2] @ np.linalg.inv(C[0]))
    A, B = relative_motions(F, C, "eye_to_hand", pairs=[[0, 2]])
    assert np.allclose(A[0], F[2] @ np.linalg.inv(F[0]))


def test_notes_derivation_constant_transforms():
    # The notes (001_...txt): eye-in-hand keeps base->target constant, eye-to-hand flange->target.
    s = random_scene(5, "eye_in_hand", rng=1)
    Z = s.flange2base @ s.X @ s.target2cam
    assert np.abs(Z - s.Z).max() < 1e-12
    s = random_scene(5, "eye_to_hand", rng=1)
    Z = invert(s.flange2base) @ s.X @ s.target2cam
    assert np.abs(Z - s.Z).max() < 1e-12


def test_motion_set_from_poses_equals_from_matrices():
    s = random_scene(9, "eye_to_hand", rng=2)
    m1 = MotionSet.from_poses(s.flange2base, s.target2cam, "eye_to_hand")
    A, B = relative_motions(s.flange2base, s.target2cam, "eye_to_hand")
    m2 = MotionSet.from_matrices(A, B)
    assert np.allclose(m1.dq_a, m2.dq_a, atol=1e-14) and np.allclose(m1.dq_b, m2.dq_b, atol=1e-14)
    assert np.allclose(m1.A, A) and np.allclose(m1.B, B)


def test_pair_indices():
    assert pair_indices(4, "all").tolist() == [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]
    assert pair_indices(4, "consecutive").tolist() == [[0, 1], [1, 2], [2, 3]]
    with pytest.raises(InputMismatchError, match="outside"):
        pair_indices(4, [[0, 4]])
    with pytest.raises(InputMismatchError, match="itself"):
        pair_indices(4, [[1, 1]])
    with pytest.raises(InputMismatchError, match="unknown pairs"):
        pair_indices(4, "random")


def test_bad_inputs_are_named():
    s = random_scene(5, "eye_in_hand", rng=0)
    with pytest.raises(InputMismatchError, match="5 robot poses but 4 camera poses"):
        relative_motions(s.flange2base, s.target2cam[:4])
    with pytest.raises(InputMismatchError, match="unknown setup"):
        relative_motions(s.flange2base, s.target2cam, setup="eye_on_hand")
    bad = s.target2cam.copy()
    bad[3, 0, 0] = np.nan
    with pytest.raises(PoseFormatError, match="target2cam: entry 3 contains NaN"):
        relative_motions(s.flange2base, bad)
    bad = s.flange2base.copy()
    bad[2, :3, :3] *= 1.1
    with pytest.raises(PoseFormatError, match="flange2base: entry 2: rotation is not orthonormal"):
        relative_motions(bad, s.target2cam)
    with pytest.raises(InputMismatchError, match="at least 2 poses"):
        relative_motions(s.flange2base[:1], s.target2cam[:1])


def test_screw_congruence_zero_for_consistent_and_large_for_wrong_convention():
    s = random_scene(10, "eye_in_hand", rng=4)
    dth, dd = screw_congruence(*relative_motions(s.flange2base, s.target2cam))
    assert dth.max() < 1e-12 and dd.max() < 1e-12
    m = MotionSet.from_poses(s.flange2base, s.target2cam, "eye_in_hand")
    dth2, dd2 = screw_congruence(m)
    assert dth2.max() < 1e-12 and dd2.max() < 1e-12
    # Robot poses inverted by mistake: each motion becomes a conjugate of its inverse, and angle and
    # pitch are invariant under inversion, so screw congruence cannot see it (diagnostics must use
    # the consistency of Z instead, which breaks).
    dth, dd = screw_congruence(*relative_motions(invert(s.flange2base), s.target2cam))
    assert dth.max() < 1e-12 and dd.max() < 1e-12
    cal = handeye.calibrate_poses(invert(s.flange2base), s.target2cam, refine="none", uncertainty=False, check=False)
    assert np.median(cal.pose_residuals[:, 1]) > 10.0  # mm
    with pytest.raises(handeye.InputMismatchError, match="robot poses are inverted"):
        handeye.calibrate_poses(invert(s.flange2base), s.target2cam, strict=True)
    answered = handeye.calibrate_poses(invert(s.flange2base), s.target2cam)  # not strict: a verdict, not a refusal
    assert answered.verdict == "inconsistent" and answered.diagnostics.convention_hint == "invert_robot_poses"
    assert any("robot poses are inverted" in n for n in answered.notes)
    # Euler sequence mixed up: the rotation angles no longer match.
    from handeye.frames.poses import format_poses, parse_poses

    wrong = parse_poses(format_poses(s.flange2base, "euler:ZYX"), "euler:XYZ")
    dth, dd = screw_congruence(*relative_motions(wrong, s.target2cam))
    assert np.median(np.degrees(dth)) > 1.0


def test_calibrate_poses_accepts_explicit_pairs():
    s = random_scene(6, "eye_in_hand", rng=5)
    cal = handeye.calibrate_poses(s.flange2base, s.target2cam, pairs=np.array([[0, 1], [1, 2], [0, 5]]), refine="none")
    assert cal.pairs.tolist() == [[0, 1], [1, 2], [0, 5]]
    assert handeye.frames.metrics.rotation_error(cal.X, s.X) < 1e-9


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_all_pairs_translation_in_o_n_equals_the_sum_over_motions(setup):
    """The translation step over all N(N-1)/2 pairs by prefix sums over the poses equals the
    normal equations summed motion by motion (noisy poses, so no term cancels by accident)."""
    from handeye.geometry.se3 import random_rotations
    from handeye.simulate import perturb_poses
    from handeye.solvers._common import translation_least_squares

    rng = np.random.default_rng(11)
    scene = random_scene(25, setup, rng=rng)
    f2b = perturb_poses(scene.flange2base, 0.01, 0.005, rng)
    t2c = perturb_poses(scene.target2cam, 0.01, 0.005, rng)
    fast = MotionSet.from_poses(f2b, t2c, setup, "all")
    assert fast.all_pairs_factors is not None
    slow = MotionSet(fast.dq_a, fast.dq_b, fast.pairs, _AB=fast._matrices())
    assert slow.all_pairs_factors is None
    for R_X in random_rotations(4, rng):
        t_fast, t_slow = translation_least_squares(fast, R_X), translation_least_squares(slow, R_X)
        assert np.abs(t_fast - t_slow).max() <= 1e-12 * max(1.0, np.abs(t_slow).max())
    # other pairings keep the motion-by-motion sum
    assert MotionSet.from_poses(f2b, t2c, setup, "consecutive").all_pairs_factors is None
    shuffled = pair_indices(25, "all")[::-1].copy()
    assert MotionSet.from_poses(f2b, t2c, setup, shuffled).all_pairs_factors is None


def test_rotation_spread_from_absolute_matrices_equals_from_quaternions():
    """The observability check of the robot-world solvers reads v v^T of the motions R_0^T R_i off
    the absolute rotation matrices; same numbers as from the motions' quaternions, half turns
    included, parallel axes still caught, both sides in one batch."""
    from scipy.spatial.transform import Rotation

    from handeye.geometry.dualquat import dq_from_matrix
    from handeye.geometry.se3 import make_transform, random_rotations
    from handeye.solvers.observability import rotation_spread, rotation_spread_absolute

    rng = np.random.default_rng(12)
    R = random_rotations(40, rng)
    R[5] = np.diag([1.0, -1.0, -1.0])  # exact half turn
    axis = np.array([0.3, 0.4, 0.5]) / np.linalg.norm([0.3, 0.4, 0.5])
    parallel = Rotation.from_rotvec(np.outer(np.linspace(0.1, np.pi, 9), axis)).as_matrix()
    R0 = random_rotations(1, rng)[0]
    for rot in (R, parallel):
        dq = dq_from_matrix(make_transform(rot, np.zeros((len(rot), 3))))
        largest, spread, e1 = rotation_spread(dq)
        # absolute poses whose motions R_0^T R_i are rot (translations play no part)
        absolute = make_transform(R0 @ np.concatenate([np.eye(3)[None], rot]), rng.normal(size=(len(rot) + 1, 3)))
        (largest_m, spread_m), e1_m = rotation_spread_absolute(np.stack([absolute, absolute]))
        for side in range(2):
            assert abs(largest - largest_m[side]) < 1e-12 and abs(spread - spread_m[side]) < 1e-7
            assert abs(abs(e1 @ e1_m[side]) - 1.0) < 1e-12
    parallel_abs = make_transform(R0 @ np.concatenate([np.eye(3)[None], parallel]), np.ones(3))
    assert rotation_spread_absolute(parallel_abs)[0][1] < 1e-7
