r"""Parameterizations of rotation tensors (seed 000, eqs. (36)–(42)) and of unit quaternions.

A rotation tensor $Z = \sum_i e'_i e_i$ (seed eq. (41)) takes the basis $e$ to the basis
$e'$; its matrix in the basis $e$ is $R$ with columns $e'_i$, the same $R$ as everywhere
in `bundledyn.lie` (rotation part of $g$, $x \mapsto Rx$). Angular velocities are
*spatial* (absolute, the seed's $\tilde\omega = \dot Z Z^T$, components in $e$) unless
said otherwise; the body angular velocity is $R^T\omega$.

Every function accepts leading batch dimensions and keeps the input dtype. Each
parameterization is singular somewhere; the docstrings say where.
"""

import jax
import jax.numpy as jnp

from ._so3 import _float, _sq, so3_hat, so3_log, so3_vee

__all__ = [
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
    "rotation_from_euler_angles",
    "euler_angles_from_rotation",
    "rotation_from_bryant_angles",
    "bryant_angles_from_rotation",
    "rotation_from_krylov_angles",
    "krylov_angles_from_rotation",
    "rotation_from_quaternion",
    "quaternion_from_rotation",
    "rotation_x",
    "rotation_y",
    "rotation_z",
    "rotation_vector_from_quaternion",
    "quaternion_from_rotation_vector",
]


def _eye(batch, dtype):
    return jnp.broadcast_to(jnp.eye(3, dtype=dtype), batch + (3, 3))


# --- vector parameter (36)–(38) ----------------------------------------------------------


def rotation_from_vector_parameter(c):
    r"""Rotation from the vector parameter $c = \tan(\chi/2)\,e$ (seed eq. (36)).

    $Z = 1 + \frac{2}{1 + c\cdot c}(\tilde c + \tilde c\,\tilde c)$. A rational function
    of $c$, smooth for every finite $c$; the half-turn $\chi = \pi$ is reached only as
    $|c| \to \infty$ (eq. (38)).

    **Arguments:**

    - `c`: vector parameter (Gibbs–Rodrigues vector), shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    c = _float(c)
    C = so3_hat(c)
    k = 2.0 / (1.0 + _sq(c))
    return _eye(c.shape[:-1], c.dtype) + k[..., None, None] * (C + C @ C)


def vector_parameter_from_rotation(R):
    r"""Vector parameter of a rotation (seed eq. (37)).

    $\tilde c = (Z - Z^T)/(1 + \operatorname{tr}Z)$, i.e.
    $c = (R - R^T)^\vee/(1 + \operatorname{tr}R)$.
    $|c| = \tan(\chi/2)$ (eq. (38)). Singular at $\chi = \pi$ ($\operatorname{tr}Z = -1$),
    where $|c| = \infty$; inaccurate as $\chi \to \pi$.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    Vector parameter $c$, shape `(..., 3)`.
    """
    R = _float(R)
    num = so3_vee(R - jnp.swapaxes(R, -1, -2))
    den = 1.0 + jnp.trace(R, axis1=-2, axis2=-1)
    return num / den[..., None]


def angular_velocity_from_vector_parameter(c, cdot, *, body=False):
    r"""Angular velocity from the vector parameter and its rate (seed, after eq. (38)).

    The seed computes $\tilde\omega = \dot Z Z^T$, the **spatial** (absolute) angular
    velocity, $\omega = \frac{2}{1 + c\cdot c}(\dot c + c\times\dot c)$, i.e.
    $\omega = (\dot R R^T)^\vee$. With `body=True` returns the body angular velocity
    $(R^T\dot R)^\vee = R^T\omega = \frac{2}{1 + c\cdot c}(\dot c - c\times\dot c)$.
    Smooth for every finite $c$.

    **Arguments:**

    - `c`: vector parameter, shape `(..., 3)`.
    - `cdot`: its time derivative, shape `(..., 3)`.
    - `body`: return the body-frame angular velocity instead of the spatial one.

    **Returns:**

    Angular velocity, shape `(..., 3)`.
    """
    c = _float(c)
    cdot = jnp.asarray(cdot, dtype=c.dtype)
    k = 2.0 / (1.0 + _sq(c))
    cross = jnp.cross(c, cdot)
    return k[..., None] * (cdot - cross if body else cdot + cross)


# --- axis and angle (39)–(40) ------------------------------------------------------------


def rotation_from_axis_angle(e, chi):
    r"""Rotation by the angle $\chi$ about the unit vector $e$ (seed eq. (39)).

    $Z = 1 + (1 - \cos\chi)\,\tilde e\,\tilde e + \sin\chi\,\tilde e$; the seed calls
    $(e, \chi)$ the Euler parameters of $Z$. Smooth in $(e, \chi)$; the pair is not
    unique at $\chi = 0$ (any axis). `e` is assumed to be a unit vector (not normalized).

    **Arguments:**

    - `e`: unit axis, shape `(..., 3)`.
    - `chi`: angle, shape `(...)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)` (leading dimensions broadcast).
    """
    e = _float(e)
    chi = jnp.asarray(chi, dtype=e.dtype)
    batch = jnp.broadcast_shapes(e.shape[:-1], chi.shape)
    e, chi = jnp.broadcast_to(e, batch + (3,)), jnp.broadcast_to(chi, batch)
    E = so3_hat(e)
    s = jnp.sin(chi)[..., None, None]
    vc = (1.0 - jnp.cos(chi))[..., None, None]
    return _eye(batch, e.dtype) + vc * (E @ E) + s * E


def axis_angle_from_rotation(R):
    r"""Unit axis $e$ and angle $\chi \in [0, \pi]$ of a rotation, via `so3_log`.

    Singular at $\chi = 0$, where the axis is undefined: there it returns
    $e = (0, 0, 1)$ (values and derivatives stay finite). At $\chi = \pi$ the sign of
    $e$ follows `so3_log`.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    `(e, chi)` with shapes `(..., 3)` and `(...)`.
    """
    w = so3_log(R)
    x = _sq(w)
    zero = x == 0.0
    x_safe = jnp.where(zero, 1.0, x)
    chi_safe = jnp.sqrt(x_safe)
    chi = jnp.where(zero, 0.0, chi_safe)
    ez = jnp.zeros_like(w).at[..., 2].set(1.0)
    e = jnp.where(zero[..., None], ez, w / chi_safe[..., None])
    return e, chi


def angular_velocity_from_axis_angle(e, chi, edot, chidot):
    r"""Spatial angular velocity of $Z(e, \chi)$ (seed eq. (40)).

    $\omega = [(1 - \cos\chi)\tilde e + \sin\chi]\,\dot e + \dot\chi\,e$, valid for
    $|e| = 1$, $e\cdot\dot e = 0$; $\omega = (\dot R R^T)^\vee$.

    **Arguments:**

    - `e`: unit axis, shape `(..., 3)`.
    - `chi`: angle, shape `(...)`.
    - `edot`: $\dot e$, shape `(..., 3)`.
    - `chidot`: $\dot\chi$, shape `(...)`.

    **Returns:**

    Angular velocity, shape `(..., 3)`.
    """
    e = _float(e)
    chi = jnp.asarray(chi, dtype=e.dtype)[..., None]
    edot = jnp.asarray(edot, dtype=e.dtype)
    chidot = jnp.asarray(chidot, dtype=e.dtype)[..., None]
    return (1.0 - jnp.cos(chi)) * jnp.cross(e, edot) + jnp.sin(chi) * edot + chidot * e


# --- Euler parameters / unit quaternions -------------------------------------------------


def rotation_from_quaternion(q):
    r"""Rotation matrix of a quaternion $q = (w, x, y, z)$, scalar part first.

    $R = \big((w^2 - |u|^2)\,1 + 2uu^T + 2w\tilde u\big)/|q|^2$, $u = (x, y, z)$: the
    quaternion is normalized implicitly, so any nonzero $q$ gives a rotation ($q$ and
    $-q$ give the same one). This is eq. (39) with $w = \cos(\chi/2)$,
    $u = \sin(\chi/2)\,e$. Singular only at $q = 0$.

    **Arguments:**

    - `q`: quaternion, shape `(..., 4)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    q = _float(q)
    w, u = q[..., 0], q[..., 1:]
    n2 = _sq(q)
    U = so3_hat(u)
    R = (
        (w * w - _sq(u))[..., None, None] * _eye(q.shape[:-1], q.dtype)
        + 2.0 * u[..., :, None] * u[..., None, :]
        + 2.0 * w[..., None, None] * U
    )
    return R / n2[..., None, None]


def quaternion_from_rotation(R):
    r"""Unit quaternion $(w, x, y, z)$ of a rotation matrix, with $w \ge 0$.

    Shepperd's method: the symmetric matrix $K = 4qq^T$ is formed from the entries of $R$
    ($K_{00} = 1 + \operatorname{tr}R$, $K_{11} = 1 + 2R_{11} - \operatorname{tr}R$, …,
    $K_{01} = R_{32} - R_{23}$, …); its column $k$ with the largest diagonal entry (a
    one-hot selection, no gather) divided by $2\sqrt{K_{kk}} \ge 2$ is $\pm q$, so no
    division by a small number ever occurs. The sign is then fixed by $w \ge 0$; at
    $w = 0$ exactly (half-turns) the pivot component is positive. Accurate to rounding
    and differentiable (with finite derivatives) for every rotation.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    Quaternion, shape `(..., 4)`.
    """
    R = _float(R)
    r = lambda i, j: R[..., i, j]
    tr = r(0, 0) + r(1, 1) + r(2, 2)
    t = jnp.stack(
        [
            1.0 + tr,
            1.0 + 2.0 * r(0, 0) - tr,
            1.0 + 2.0 * r(1, 1) - tr,
            1.0 + 2.0 * r(2, 2) - tr,
        ],
        axis=-1,
    )  # 4 w², 4 x², 4 y², 4 z²
    # off-diagonal combinations: 4wx, 4wy, 4wz, 4xy, 4xz, 4yz
    wx = r(2, 1) - r(1, 2)
    wy = r(0, 2) - r(2, 0)
    wz = r(1, 0) - r(0, 1)
    xy = r(0, 1) + r(1, 0)
    xz = r(0, 2) + r(2, 0)
    yz = r(1, 2) + r(2, 1)
    K = jnp.stack(
        [
            jnp.stack([t[..., 0], wx, wy, wz], axis=-1),
            jnp.stack([wx, t[..., 1], xy, xz], axis=-1),
            jnp.stack([wy, xy, t[..., 2], yz], axis=-1),
            jnp.stack([wz, xz, yz, t[..., 3]], axis=-1),
        ],
        axis=-2,
    )  # = 4 q qᵀ
    # column k of 4 q qᵀ divided by 2 sqrt(t_k) = 4 |q_k| is ±q; t_k ≥ 1 for the largest
    onehot = jax.nn.one_hot(jnp.argmax(t, axis=-1), 4, dtype=R.dtype)
    tk = jnp.sum(t * onehot, axis=-1)
    out = jnp.einsum("...ij,...j->...i", K, onehot) / (2.0 * jnp.sqrt(tk))[..., None]
    return jnp.where((out[..., :1] < 0.0), -out, out)


_ATAN_SERIES = tuple(1.0 / (2 * k + 1) for k in range(12))  # atan(t)/t in powers of -t²


def rotation_vector_from_quaternion(q):
    r"""The rotation vector $\varphi$, $|\varphi| \le \pi$, of a quaternion $(w, x, y, z)$, unit or not.

    $\varphi = 2\operatorname{atan2}(|u|, w)\,u/|u|$ after flipping the sign so that
    $w \ge 0$: the same as `so3_log(rotation_from_quaternion(q))`, without the matrix.
    Near the identity ($|u|^2 < 10^{-2} w^2$) the factor $\arctan(|u|/w)/|u|$ is its
    series in $|u|^2/w^2$, so values and derivatives are exact at $\varphi = 0$.

    **Arguments:**

    - `q`: quaternion, scalar part first, shape `(..., 4)`.

    **Returns:**

    The rotation vector, shape `(..., 3)`.
    """
    q = _float(q)
    q = jnp.where(q[..., :1] < 0, -q, q)
    w, u = q[..., 0], q[..., 1:]
    x2 = jnp.sum(u * u, axis=-1)
    small = x2 < 1e-2 * w * w
    w_small = jnp.where(small, w, 1.0)
    y = jnp.where(small, x2, 0.0) / (w_small * w_small)
    series = _ATAN_SERIES[-1]
    for c in reversed(_ATAN_SERIES[:-1]):
        series = c - y * series
    f_small = series / w_small
    x2_gen = jnp.where(small, 1.0, x2)
    n = jnp.sqrt(x2_gen)
    f_gen = jnp.arctan2(n, jnp.where(small, 0.0, w)) / n
    return (2.0 * jnp.where(small, f_small, f_gen))[..., None] * u


def quaternion_from_rotation_vector(phi):
    r"""The unit quaternion $(\cos\frac\theta2, \sin\frac\theta2\,\varphi/\theta)$, $\theta = |\varphi|$, of a rotation vector.

    A Taylor branch at $\theta = 0$ keeps values and derivatives exact there.

    **Arguments:**

    - `phi`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Quaternion, scalar part first, shape `(..., 4)`.
    """
    phi = _float(phi)
    x = jnp.sum(phi * phi, axis=-1)
    small = x < 1e-4
    xs = jnp.where(small, 1.0, x)
    theta = jnp.sqrt(xs)
    half_sinc = jnp.where(
        small,
        0.5 - x / 48.0 + x * x / 3840.0 - x**3 / 645120.0,
        jnp.sin(0.5 * theta) / theta,
    )
    w = jnp.where(small, 1.0 - x / 8.0 + x * x / 384.0 - x**3 / 46080.0, jnp.cos(0.5 * theta))
    return jnp.concatenate([w[..., None], half_sinc[..., None] * phi], axis=-1)


def rotation_from_euler_parameters(q0, q):
    r"""Rotation from the Euler–Rodrigues parameters $(q_0, q) = (\cos\frac\chi2, \sin\frac\chi2e)$.

    Eq. (39) rewritten with half angles:
    $Z = (q_0^2 - q\cdot q)\,1 + 2qq^T + 2q_0\tilde q$ for $q_0^2 + q\cdot q = 1$ (the
    quaternion $(q_0, q)$; normalized implicitly as in `rotation_from_quaternion`). The
    seed names the pair $(e, \chi)$ of eq. (39) the Euler parameters; see
    `rotation_from_axis_angle` for that form. Singular only at $(q_0, q) = 0$.

    **Arguments:**

    - `q0`: scalar part, shape `(...)`.
    - `q`: vector part, shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    q = _float(q)
    q0 = jnp.asarray(q0, dtype=q.dtype)
    batch = jnp.broadcast_shapes(q0.shape, q.shape[:-1])
    quat = jnp.concatenate(
        [jnp.broadcast_to(q0, batch)[..., None], jnp.broadcast_to(q, batch + (3,))], axis=-1
    )
    return rotation_from_quaternion(quat)


def euler_parameters_from_rotation(R):
    r"""Euler parameters $(q_0, q) = (\cos(\chi/2), \sin(\chi/2)e)$ with $q_0 \ge 0$.

    Via `quaternion_from_rotation` (Shepperd's method); nonsingular everywhere.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    `(q0, q)` with shapes `(...)` and `(..., 3)`.
    """
    quat = quaternion_from_rotation(R)
    return quat[..., 0], quat[..., 1:]


# --- unit vector and angle (41)–(42) -----------------------------------------------------


def _unit_vector_frame(e3, a):
    e3 = _float(e3)
    e3, a = jnp.broadcast_arrays(e3, jnp.asarray(a, dtype=e3.dtype))
    axe = jnp.cross(a, e3)
    p = axe / jnp.sqrt(_sq(axe))[..., None]
    return e3, a, axe, p


def rotation_from_unit_vector_and_angle(e3, phi, a):
    r"""Rotation tensor (41) from the unit vector $e'_3$ and the angle $\phi$ (seed, before (42)).

    With the fixed vector $a$ and $p = a\times e'_3/|a\times e'_3|$, the intermediate basis
    is $e''= (p,\ e'_3\times p,\ e'_3)$ and
    $e'_1 = \cos\phi\,p + \sin\phi\,e'_3\times p$,
    $e'_2 = -\sin\phi\,p + \cos\phi\,e'_3\times p$; returns $R = [e'_1\ e'_2\ e'_3]$.
    Singular where $a \times e'_3 = 0$ ($e'_3 \parallel a$). $a = e_3$ gives the Euler
    angles, $a = e_1$ the Bryant angles, $a = e_2$ the Krylov angles.

    **Arguments:**

    - `e3`: unit vector $e'_3$ (third body axis in space), shape `(..., 3)`.
    - `phi`: angle from $p$ to $e'_1$ about $e'_3$, shape `(...)`.
    - `a`: fixed reference vector, shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    e3, a, _, p = _unit_vector_frame(e3, a)
    phi = jnp.asarray(phi, dtype=e3.dtype)[..., None]
    q = jnp.cross(e3, p)
    e1 = jnp.cos(phi) * p + jnp.sin(phi) * q
    e2 = -jnp.sin(phi) * p + jnp.cos(phi) * q
    batch = jnp.broadcast_shapes(e1.shape, e2.shape, e3.shape)
    cols = [jnp.broadcast_to(x, batch) for x in (e1, e2, e3)]
    return jnp.stack(cols, axis=-1)


def unit_vector_and_angle_from_rotation(R, a):
    r"""Inverse of `rotation_from_unit_vector_and_angle`: $(e'_3, \phi)$ from $R$.

    $e'_3 = Re_3$; $\phi = \operatorname{atan2}((e'_3\times p)\cdot e'_1,\ p\cdot e'_1)$.
    Singular where $e'_3 \parallel a$.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.
    - `a`: fixed reference vector, shape `(..., 3)`.

    **Returns:**

    `(e3, phi)` with shapes `(..., 3)` and `(...)`.
    """
    R = _float(R)
    e3, _, _, p = _unit_vector_frame(R[..., :, 2], a)
    e1 = R[..., :, 0]
    phi = jnp.arctan2(jnp.sum(jnp.cross(e3, p) * e1, -1), jnp.sum(p * e1, -1))
    return e3, phi


def angular_velocity_from_unit_vector_and_angle(e3, phi, e3dot, phidot, a):
    r"""Spatial angular velocity of the basis $e'$ (seed eq. (42)).

    $\omega' = \dot\phi\,e'_3 + A\,\dot e'_3$,
    $A = \frac{a\cdot e'_3}{|a\times e'_3|}\,e'_3 p^T + \tilde e'_3$, for the
    parameterization of `rotation_from_unit_vector_and_angle` ($|e'_3| = 1$,
    $e'_3\cdot\dot e'_3 = 0$). Singular where $e'_3 \parallel a$. `phi` does not enter
    (kept for a uniform signature).

    **Arguments:**

    - `e3`: unit vector $e'_3$, shape `(..., 3)`.
    - `phi`: angle, shape `(...)` (unused).
    - `e3dot`: $\dot e'_3$, shape `(..., 3)`.
    - `phidot`: $\dot\phi$, shape `(...)`.
    - `a`: fixed reference vector, shape `(..., 3)`.

    **Returns:**

    Angular velocity $\omega' = (\dot R R^T)^\vee$, shape `(..., 3)`.
    """
    del phi
    e3, a, axe, p = _unit_vector_frame(e3, a)
    e3dot = jnp.asarray(e3dot, dtype=e3.dtype)
    phidot = jnp.asarray(phidot, dtype=e3.dtype)[..., None]
    k = (jnp.sum(a * e3, -1) / jnp.sqrt(_sq(axe)))[..., None]
    return phidot * e3 + k * e3 * jnp.sum(p * e3dot, -1)[..., None] + jnp.cross(e3, e3dot)


# --- elementary rotations and angle sequences --------------------------------------------


def _elementary(angle, i):
    angle = _float(angle)
    c, s = jnp.cos(angle), jnp.sin(angle)
    o, z = jnp.ones_like(c), jnp.zeros_like(c)
    if i == 0:
        rows = [[o, z, z], [z, c, -s], [z, s, c]]
    elif i == 1:
        rows = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        rows = [[c, -s, z], [s, c, z], [z, z, o]]
    return jnp.stack([jnp.stack(r, axis=-1) for r in rows], axis=-2)


def rotation_x(angle):
    """Rotation by `angle` about the first axis, shape `(...)` → `(..., 3, 3)`.

    **Arguments:**

    - `angle`: shape `(...)`.

    **Returns:**

    Shape `(..., 3, 3)`.
    """
    return _elementary(angle, 0)


def rotation_y(angle):
    """Rotation by `angle` about the second axis, shape `(...)` → `(..., 3, 3)`.

    **Arguments:**

    - `angle`: shape `(...)`.

    **Returns:**

    Shape `(..., 3, 3)`.
    """
    return _elementary(angle, 1)


def rotation_z(angle):
    """Rotation by `angle` about the third axis, shape `(...)` → `(..., 3, 3)`.

    **Arguments:**

    - `angle`: shape `(...)`.

    **Returns:**

    Shape `(..., 3, 3)`.
    """
    return _elementary(angle, 2)


def _split(angles):
    angles = _float(angles)
    return angles[..., 0], angles[..., 1], angles[..., 2]


def rotation_from_euler_angles(angles):
    r"""Rotation from classical Euler angles $(\psi, \theta, \phi)$, sequence z-x-z.

    $R = R_3(\psi)\,R_1(\theta)\,R_3(\phi)$ (precession about $e_3$, nutation about the
    line of nodes $p$, proper rotation about $e'_3$): the seed's construction (41)–(42)
    with $a = e_3$. Smooth; the angles are singular at $\theta = 0, \pi$.

    **Arguments:**

    - `angles`: $(\psi, \theta, \phi)$, shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    psi, theta, phi = _split(angles)
    return rotation_z(psi) @ rotation_x(theta) @ rotation_z(phi)


def euler_angles_from_rotation(R):
    r"""Classical Euler angles $(\psi, \theta, \phi)$ (z-x-z) of a rotation matrix.

    $\theta = \operatorname{atan2}(\sqrt{R_{13}^2 + R_{23}^2}, R_{33}) \in [0, \pi]$,
    $\psi = \operatorname{atan2}(R_{13}, -R_{23})$, $\phi = \operatorname{atan2}(R_{31}, R_{32})$,
    $\psi, \phi \in (-\pi, \pi]$. Singular (gimbal lock: only $\psi \pm \phi$ defined) at
    $\theta = 0, \pi$, i.e. $e'_3 \parallel e_3$.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    `(..., 3)` array $(\psi, \theta, \phi)$.
    """
    R = _float(R)
    st = jnp.sqrt(R[..., 0, 2] ** 2 + R[..., 1, 2] ** 2)
    theta = jnp.arctan2(st, R[..., 2, 2])
    psi = jnp.arctan2(R[..., 0, 2], -R[..., 1, 2])
    phi = jnp.arctan2(R[..., 2, 0], R[..., 2, 1])
    return jnp.stack([psi, theta, phi], axis=-1)


def rotation_from_bryant_angles(angles):
    r"""Rotation from Bryant (Cardan) angles $(\alpha, \beta, \gamma)$, sequence x-y-z.

    $R = R_1(\alpha)\,R_2(\beta)\,R_3(\gamma)$ (intrinsic rotations about $e_1$, the node
    line $\pm p$, $e'_3$): the seed's construction with $a = e_1$. Singular at
    $\beta = \pm\pi/2$ ($e'_3 \parallel e_1$).

    **Arguments:**

    - `angles`: $(\alpha, \beta, \gamma)$, shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    a, b, g = _split(angles)
    return rotation_x(a) @ rotation_y(b) @ rotation_z(g)


def bryant_angles_from_rotation(R):
    r"""Bryant angles $(\alpha, \beta, \gamma)$ (x-y-z) of a rotation matrix.

    $\beta = \operatorname{atan2}(R_{13}, \sqrt{R_{11}^2 + R_{12}^2}) \in [-\pi/2, \pi/2]$,
    $\alpha = \operatorname{atan2}(-R_{23}, R_{33})$,
    $\gamma = \operatorname{atan2}(-R_{12}, R_{11})$.
    Singular at $\beta = \pm\pi/2$.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    `(..., 3)` array $(\alpha, \beta, \gamma)$.
    """
    R = _float(R)
    cb = jnp.sqrt(R[..., 0, 0] ** 2 + R[..., 0, 1] ** 2)
    beta = jnp.arctan2(R[..., 0, 2], cb)
    alpha = jnp.arctan2(-R[..., 1, 2], R[..., 2, 2])
    gamma = jnp.arctan2(-R[..., 0, 1], R[..., 0, 0])
    return jnp.stack([alpha, beta, gamma], axis=-1)


def rotation_from_krylov_angles(angles):
    r"""Rotation from Krylov angles $(\psi, \theta, \phi)$, sequence y-x-z.

    $R = R_2(\psi)\,R_1(\theta)\,R_3(\phi)$: the seed's construction with $a = e_2$ (it
    gives no further detail), read in the ship-theory way with $e_2$ vertical and $e'_3$
    the longitudinal body axis: yaw (course) $\psi$ about the vertical, pitch (trim)
    $\theta$ about the node line $\perp e_2, e'_3$, roll (heel) $\phi$ about $e'_3$.
    Singular at $\theta = \pm\pi/2$ ($e'_3 \parallel e_2$).

    **Arguments:**

    - `angles`: $(\psi, \theta, \phi)$, shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    psi, theta, phi = _split(angles)
    return rotation_y(psi) @ rotation_x(theta) @ rotation_z(phi)


def krylov_angles_from_rotation(R):
    r"""Krylov angles $(\psi, \theta, \phi)$ (y-x-z) of a rotation matrix.

    $\theta = \operatorname{atan2}(-R_{23}, \sqrt{R_{21}^2 + R_{22}^2}) \in [-\pi/2, \pi/2]$,
    $\psi = \operatorname{atan2}(R_{13}, R_{33})$, $\phi = \operatorname{atan2}(R_{21}, R_{22})$.
    Singular at $\theta = \pm\pi/2$.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    `(..., 3)` array $(\psi, \theta, \phi)$.
    """
    R = _float(R)
    ct = jnp.sqrt(R[..., 1, 0] ** 2 + R[..., 1, 1] ** 2)
    theta = jnp.arctan2(-R[..., 1, 2], ct)
    psi = jnp.arctan2(R[..., 0, 2], R[..., 2, 2])
    phi = jnp.arctan2(R[..., 1, 0], R[..., 1, 1])
    return jnp.stack([psi, theta, phi], axis=-1)
