"""The leaning rolling disc on both sides: sympy's `KanesMethod` with the contact's two
nonholonomic constraints, and bundledyn's `RigidBody` in a `RollingMode` on a `DiscContact`.

Coordinates of the peer (the world's $z$ up): heading $q_1$, tilt $q_2$ and spin $q_3$
($R = R_z(q_1)R_x(q_2)R_y(q_3)$, the axle the body's $y$), the contact point $(q_4, q_5)$;
speeds $u_i = \\dot q_i$, $u_4, u_5$ dependent."""

import numpy as np

from benchmarks.nonholonomic.peer import KaneModel

NAME = "rolling disc"
MASS, RADIUS, GRAVITY = 1.5, 0.2, 9.81
# (axial, diametral) moments of inertia: a uniform disc and a ring.
SHAPES = {
    "uniform disc": (MASS * RADIUS**2 / 2, MASS * RADIUS**2 / 4),
    "ring": (MASS * RADIUS**2, MASS * RADIUS**2 / 2),
}
SPINS = (4.0, 8.0, 12.0)  # spin rates (rad/s): the family's energies


def kane_model(shape):
    """The disc by Kane's method with its rolling constraints (sympy's documented setup, the
    contact point's position added as coordinates with dependent speeds)."""
    import sympy as sm
    import sympy.physics.mechanics as me

    q1, q2, q3, q4, q5 = me.dynamicsymbols("q1:6")
    u1, u2, u3, u4, u5 = me.dynamicsymbols("u1:6")
    r, m, g, axial, diametral = sm.symbols("r m g I_a I_d")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    L.set_ang_vel(N, u1 * N.z + u2 * L.x)  # in the speeds, so no q' is left to substitute
    R.set_ang_vel(N, u1 * N.z + u2 * L.x + u3 * L.y)
    contact = me.Point("C")
    contact.set_vel(N, u4 * N.x + u5 * N.y)
    centre = contact.locatenew("D", r * L.z)
    centre.set_vel(N, contact.vel(N) + (r * L.z).dt(N))
    touching = centre.locatenew("P", -r * L.z)  # the disc's material point at the contact
    touching.v2pt_theory(centre, N, R)
    constraints = [touching.vel(N) & N.x, touching.vel(N) & N.y]
    q, u = [q1, q2, q3, q4, q5], [u1, u2, u3, u4, u5]
    method = me.KanesMethod(
        N,
        q_ind=q,
        u_ind=u[:3],
        u_dependent=u[3:],
        kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u, strict=True)],
        velocity_constraints=constraints,
    )
    disc = me.RigidBody("disc", centre, R, m, (me.inertia(L, diametral, axial, diametral), centre))
    method.kanes_equations([disc], [(centre, -m * g * N.z)])
    values = dict(
        zip((r, m, g, axial, diametral), (RADIUS, MASS, GRAVITY, *SHAPES[shape]), strict=True)
    )
    return KaneModel(method, constraints, values)


def members(quick):
    """The family: dicts with a `label`, the model `variant` (the shape), the peer's
    coordinates `q` and independent speeds `u`: random tilts and rates at each spin."""
    rng = np.random.default_rng(2026_11_28)
    shapes = ["uniform disc"] if quick else list(SHAPES)
    spins = SPINS[1:2] if quick else SPINS
    out = []
    for shape in shapes:
        for spin in spins:
            q = np.array([rng.uniform(-np.pi, np.pi), rng.uniform(0.1, 0.5), 0.0, 0.0, 0.0])
            u = np.array([rng.normal(0.0, 1.0), rng.normal(0.0, 0.5), spin])
            out.append({"label": f"{shape}, spin {spin:g} rad/s", "variant": shape, "q": q, "u": u})
    return out


def _rotations(q):
    """$R_z(q_1)R_x(q_2)R_y(q_3)$ for states `(n, 5+)`, and the tilted frame $R_z R_x$."""
    c1, s1, c2, s2, c3, s3 = (f(q[:, i]) for i in (0, 1, 2) for f in (np.cos, np.sin))
    one, zero = np.ones_like(c1), np.zeros_like(c1)
    Rz = np.stack([[c1, -s1, zero], [s1, c1, zero], [zero, zero, one]]).transpose(2, 0, 1)
    Rx = np.stack([[one, zero, zero], [zero, c2, -s2], [zero, s2, c2]]).transpose(2, 0, 1)
    Ry = np.stack([[c3, zero, s3], [zero, one, zero], [-s3, zero, c3]]).transpose(2, 0, 1)
    tilted = Rz @ Rx
    return tilted @ Ry, tilted


def poses(x):
    """The disc's orientation `(n, 3, 3)` and centre `(n, 3)` at the peer's states `(n, 10)`."""
    rotation, tilted = _rotations(x)
    centre = np.stack([x[:, 3], x[:, 4], np.zeros(len(x))], axis=1) + RADIUS * tilted[:, :, 2]
    return rotation, centre


def body_angular_velocity(x):
    """$R^T\\omega$ at one peer state, $\\omega = u_1 e_z + u_2 L_x + u_3 L_y$."""
    rotation, tilted = (a[0] for a in _rotations(x[None]))
    omega = x[5] * np.array([0.0, 0.0, 1.0]) + x[6] * tilted[:, 0] + x[7] * tilted[:, 1]
    return rotation.T @ omega


def ours_model(shape):
    """bundledyn's disc: a rigid body rolling on the plane $z = 0$ under gravity (a `Scene`)."""
    import jax.numpy as jnp

    import bundledyn as bd

    axial, diametral = SHAPES[shape]
    inertia = jnp.diag(jnp.array([diametral, axial, diametral]))
    body = bd.RigidBody(MASS, jnp.zeros(3), inertia)
    return bd.Scene(body, [bd.Gravity(GRAVITY)], mode=bd.RollingMode(bd.DiscContact(RADIUS)))


def initial_states(scene, speeds, member):
    """`(bundledyn's State, the peer's state)` of a member; `speeds` completes the peer's
    speeds with the dependent ones (`peer.dependent_speeds`)."""
    x0 = np.concatenate([member["q"], speeds(member["q"], member["u"])])
    rotation, centre = (a[0] for a in poses(x0[None]))
    g = np.eye(4)
    g[:3, :3], g[:3, 3] = rotation, centre
    return scene.mode.state(g, body_angular_velocity(x0)), x0


def simulate(scene, state, ts, rtol):
    """bundledyn's trajectory at `ts`: poses `(n, 4, 4)`."""
    import diffrax

    import bundledyn as bd

    saveat = diffrax.SaveAt(ts=ts)
    return bd.simulate(scene, state, ts[-1], rtol=rtol, atol=rtol, saveat=saveat).g


def disagreement(ours, theirs):
    """The largest difference of orientation entries and centre coordinates at the saves."""
    rotation, centre = poses(theirs)
    ours = np.asarray(ours)
    return float(
        max(np.max(np.abs(ours[:, :3, :3] - rotation)), np.max(np.abs(ours[:, :3, 3] - centre)))
    )
