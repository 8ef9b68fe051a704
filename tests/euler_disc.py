"""The tilting disc in Euler angles, written out in sines and cosines: the independent
derivation the rolling modes' tests compare with (`test_rolling.py`, `test_rolling_wheel.py`)."""

import jax
import jax.numpy as jnp

import bundledyn as bd

DISC_MASS, DISC_RADIUS = 1.5, 0.2
# A uniform thin disc, its axle along the body's y axis.
DIAMETRAL, AXIAL = DISC_MASS * DISC_RADIUS**2 / 4, DISC_MASS * DISC_RADIUS**2 / 2
DISC_INERTIA = jnp.diag(jnp.array([DIAMETRAL, AXIAL, DIAMETRAL]))


def axis_rotation(axis, angle):
    """The rotation by `angle` about coordinate axis `axis`, written out in sines and cosines
    (not by the library's exponential: an independent derivation, and a small program to
    differentiate three times)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R = jnp.zeros((3, 3), dtype=c.dtype).at[axis, axis].set(1.0)
    return R.at[i, i].set(c).at[j, j].set(c).at[j, i].set(s).at[i, j].set(-s)


def orientation(q):
    """$R = R_z(\\varphi)R_x(\\theta)R_y(\\psi)$: heading, tilt from upright, spin about the axle."""
    return axis_rotation(2, q[2]) @ axis_rotation(0, q[3]) @ axis_rotation(1, q[4])


def body_angular_velocity(q, qdot):
    R, R_dot = jax.jvp(orientation, (q,), (qdot,))
    return bd.lie.so3_vee(R.T @ R_dot)


def centre_velocity(q, qdot):
    # the centre is at height a cos(theta) above the contact
    return jnp.stack([qdot[0], qdot[1], -DISC_RADIUS * jnp.sin(q[3]) * qdot[3]])


def contact_velocity(q, qdot):
    lowest = axis_rotation(2, q[2]) @ jnp.stack([0.0 * q[3], -jnp.sin(q[3]), jnp.cos(q[3])])
    omega = orientation(q) @ body_angular_velocity(q, qdot)
    return centre_velocity(q, qdot) + jnp.cross(omega, -DISC_RADIUS * lowest)
