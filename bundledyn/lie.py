r"""Lie-group toolkit: SO(3), SE(3), their algebras and rotation parameterizations.

Conventions (architecture §1), fixed for the whole library:

- $g = (R, p) \in SE(3)$ is a $4\times4$ homogeneous matrix acting $x \mapsto Rx + p$.
- A twist is $\xi = (\omega, v) \in \mathbb R^6$, **angular first**;
  `hat(ξ)` $= \begin{pmatrix}\tilde\omega & v\\0&0\end{pmatrix}$, `hat(ω)` $= \tilde\omega$.
- $[X, Y] = (\omega_X\times\omega_Y,\ \omega_X\times v_Y - \omega_Y\times v_X)$, `ad(X) Y = [X, Y]`.
- `Ad(g)` $= \begin{pmatrix}R&0\\\tilde pR&R\end{pmatrix}$, so that
  $(\mathrm{Ad}_g X)^\wedge = g\hat X g^{-1}$.
- Wrenches $(\tau, f)$: `coAd(g)` $= \mathrm{Ad}_{g^{-1}}^T$, `coad(X)` $= -\mathrm{ad}_X^T$ (`coad_action(X, mu)` applies it);
  `klein(X, Y)` $= \omega_X\cdot v_Y + \omega_Y\cdot v_X$.
- `dexp` is left-trivialized: $\exp(X)^{-1}\frac{d}{dt}\exp(X) = (\mathrm{dexp}(X)\dot X)^\wedge$;
  with $g = g_0\exp(\Omega)$, $\dot g = g\hat\xi \iff \dot\Omega = \mathrm{dexp}^{-1}(\Omega)\xi$.
- All functions take leading batch dimensions, keep the input dtype, and have finite,
  exact derivatives at $\theta = 0$ and up to $\theta = \pi$ (Taylor branches, safe `where`).
"""

from ._lie._rotations import (
    angular_velocity_from_axis_angle,
    angular_velocity_from_unit_vector_and_angle,
    angular_velocity_from_vector_parameter,
    axis_angle_from_rotation,
    bryant_angles_from_rotation,
    euler_angles_from_rotation,
    euler_parameters_from_rotation,
    krylov_angles_from_rotation,
    quaternion_from_rotation,
    quaternion_from_rotation_vector,
    rotation_from_axis_angle,
    rotation_from_bryant_angles,
    rotation_from_euler_angles,
    rotation_from_euler_parameters,
    rotation_from_krylov_angles,
    rotation_from_quaternion,
    rotation_from_unit_vector_and_angle,
    rotation_from_vector_parameter,
    rotation_vector_from_quaternion,
    rotation_x,
    rotation_y,
    rotation_z,
    unit_vector_and_angle_from_rotation,
    vector_parameter_from_rotation,
)
from ._lie._se3 import (
    Ad,
    ad,
    bracket,
    coAd,
    coad,
    coad_action,
    dexp,
    dexp_inv,
    exp,
    hat,
    klein,
    log,
    se3_dexp,
    se3_dexp_inv,
    se3_exp,
    se3_from_rotation_translation,
    se3_hat,
    se3_inv,
    se3_log,
    se3_rotation,
    se3_translation,
    se3_vee,
    vee,
)
from ._lie._so3 import (
    so3_dexp,
    so3_dexp_inv,
    so3_exp,
    so3_hat,
    so3_left_jacobian,
    so3_left_jacobian_inv,
    so3_log,
    so3_vee,
)

__all__ = [
    # algebra
    "hat",
    "vee",
    "so3_hat",
    "so3_vee",
    "se3_hat",
    "se3_vee",
    "bracket",
    "ad",
    "coad",
    "coad_action",
    "klein",
    # group
    "exp",
    "log",
    "so3_exp",
    "so3_log",
    "se3_exp",
    "se3_log",
    "se3_inv",
    "se3_from_rotation_translation",
    "se3_rotation",
    "se3_translation",
    "Ad",
    "coAd",
    # differentials of exp
    "dexp",
    "dexp_inv",
    "so3_dexp",
    "so3_dexp_inv",
    "se3_dexp",
    "se3_dexp_inv",
    "so3_left_jacobian",
    "so3_left_jacobian_inv",
    # rotation parameterizations
    "rotation_from_vector_parameter",
    "vector_parameter_from_rotation",
    "angular_velocity_from_vector_parameter",
    "rotation_from_euler_parameters",
    "euler_parameters_from_rotation",
    "rotation_from_axis_angle",
    "axis_angle_from_rotation",
    "angular_velocity_from_axis_angle",
    "rotation_from_unit_vector_and_angle",
    "unit_vector_and_angle_from_rotation",
    "angular_velocity_from_unit_vector_and_angle",
    "rotation_x",
    "rotation_y",
    "rotation_z",
    "rotation_from_euler_angles",
    "euler_angles_from_rotation",
    "rotation_from_bryant_angles",
    "bryant_angles_from_rotation",
    "rotation_from_krylov_angles",
    "krylov_angles_from_rotation",
    "rotation_from_quaternion",
    "quaternion_from_rotation",
    "rotation_vector_from_quaternion",
    "quaternion_from_rotation_vector",
]
