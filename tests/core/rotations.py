"""Rotations for building test cases: axis-angle quaternions, ZYZ Euler angles and the dense SH rotation matrix.

Only the tests need these; the add-on gets its rotations from Blender (matrices and quaternions) and turns
coefficients with prt_addon.core.rotation.
"""

import math

import numpy as np

from prt_addon.core import rotation


def quaternion_from_axis_angle(axis, angle):
    """Unit quaternion (w, x, y, z) rotating by `angle` radians about `axis` (right hand)."""
    axis = np.asarray(axis, dtype=np.float64)
    half = 0.5 * angle
    return np.concatenate([[math.cos(half)], math.sin(half) * axis / np.linalg.norm(axis)])


def matrix_from_euler_zyz(alpha, beta, gamma):
    """Rz(alpha) @ Ry(beta) @ Rz(gamma)."""
    return _rotation_z(alpha) @ _rotation_y(beta) @ _rotation_z(gamma)


def rotation_matrix(order, R):
    """Dense block-diagonal (order², order²) matrix of rotation.band_matrices(order, R)."""
    dense = np.zeros((order * order, order * order))
    for l, block in enumerate(rotation.band_matrices(order, R)):
        dense[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2] = block
    return dense


def _rotation_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotation_y(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
