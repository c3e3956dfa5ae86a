"""Hypothesis strategies for rotations, transforms and dual quaternions."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from handeye.geometry.se3 import make_transform

finite = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_infinity=False)
lengths = st.floats(min_value=-2.0, max_value=2.0, allow_nan=False, allow_infinity=False)


@st.composite
def unit_quaternions(draw) -> np.ndarray:
    q = np.array([draw(finite) for _ in range(4)])
    n = np.linalg.norm(q)
    if n < 1e-3:  # direction undefined: use the identity instead of an ill-defined normalisation
        return np.array([1.0, 0.0, 0.0, 0.0])
    return q / n


@st.composite
def transforms(draw) -> np.ndarray:
    q = draw(unit_quaternions())
    t = np.array([draw(lengths) for _ in range(3)])
    return make_transform(Rotation.from_quat(q, scalar_first=True).as_matrix(), t)
