"""Holonomic constraints among shape coordinates solved for the dependent ones
(`ConstrainedSystem`, `JointCoupling`, seed 001 §54): against the unconstrained system's
equations with Lagrange multipliers for the constraints, conserved energy, and the coupling's
own residual."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import chain

import bundledyn as bd
from bundledyn._dynamics import reference_accelerations

GRAVITY = bd.Gravity(9.81, (0.2, -0.1, -1.0))


def _coupled_chain():
    """`chain(4)`: a hinge (q0), a universal joint (q1, q2) and a ball (q3..q5). The universal
    joint's second angle follows the hinge by a quadratic, the ball's last coordinate is
    held, and its first follows the universal joint's first angle linearly."""
    system = chain(4)
    coupling = bd.JointCoupling(
        system.shape_dim,
        [(2, 0, (0.1, 0.5, -0.3)), (5, None, (0.05,)), (3, 1, (0.0, -0.8))],
        reference=jnp.array([0.1, -0.2, 0.0, 0.3, 0.0, 0.2]),
    )
    return system, coupling


def _multiplier_accelerations(system, coupling, q, xi, qdot):
    r"""$(\dot\xi, \ddot q)$ of the unconstrained system under gravity with the constraints'
    reactions $A^T\lambda$, $A = \partial f/\partial q$, chosen so that $A\ddot q + \dot A\dot q
    = 0$: the accelerations are affine in $\lambda$ through $G^{-1}$."""
    F, Q = GRAVITY.generalized_force(system, bd.Kinematics(0.0, jnp.eye(4), q, xi, qdot))
    free = jnp.concatenate(reference_accelerations(system, q, xi, qdot, F, Q))
    A = jax.jacfwd(coupling.residual)(q)
    A_dot_qdot = jax.jvp(lambda q: jax.jacfwd(coupling.residual)(q) @ qdot, (q,), (qdot,))[1]
    G = system.metric(q)
    d = system.shape_dim
    lift = jnp.concatenate([jnp.zeros((A.shape[0], 6)), A], axis=1).T  # reactions on q only
    response = jnp.linalg.solve(G, lift)  # acceleration per unit multiplier
    lam = jnp.linalg.solve(A @ response[6:], -(A @ free[6:] + A_dot_qdot))
    acc = free + response @ lam
    assert acc.shape == (6 + d,)
    return acc[:6], acc[6:]


@eqx.filter_jit
def _both(system, coupling, p, xi, pdot):
    constrained = bd.ConstrainedSystem(system, coupling)
    F, Q = GRAVITY.generalized_force(constrained, bd.Kinematics(0.0, jnp.eye(4), p, xi, pdot))
    xi_dot, pddot = reference_accelerations(constrained, p, xi, pdot, F, Q)
    # the full shape's acceleration along the motion: d²/dt² Φ(p(t))
    q, qdot = jax.jvp(coupling, (p,), (pdot,))
    qddot = jax.jvp(lambda p, v: jax.jvp(coupling, (p,), (v,))[1], (p, pdot), (pdot, pddot))[1]
    return (xi_dot, qddot), _multiplier_accelerations(system, coupling, q, xi, qdot)


def test_the_constrained_motion_is_the_one_with_lagrange_multipliers():
    system, coupling = _coupled_chain()
    m = len(coupling.free)
    assert m == 3
    for key in jax.random.split(jax.random.PRNGKey(3), 3):
        k = jax.random.split(key, 3)
        p = 0.6 * jax.random.normal(k[0], (m,))
        xi = jax.random.normal(k[1], (6,))
        pdot = jax.random.normal(k[2], (m,))
        ours, reference = _both(system, coupling, p, xi, pdot)
        for a, b in zip(ours, reference, strict=True):
            scale = float(jnp.max(jnp.abs(b)))
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-11 * scale)


def _energy_kept_through_simulate(scene, state, constraints):
    """Simulate 1 s, check the energy is kept to 1e-9 and that the trajectory reports the
    constraints' residual at the full shapes, and return the first free coordinate along the
    solve and the largest residual."""
    ts = jnp.linspace(0.0, 1.0, 11)
    traj = bd.simulate(scene, state, 1.0, rtol=1e-11, atol=1e-11, saveat=diffrax.SaveAt(ts=ts))
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-9)
    residual = np.asarray(jax.jit(jax.vmap(lambda p: constraints.residual(constraints(p))))(traj.q))
    np.testing.assert_allclose(traj.constraint_residual(), residual, rtol=0, atol=1e-15)
    return np.asarray(traj.q[:, 0]), float(np.max(np.abs(residual)))


def test_a_coupled_chain_keeps_its_energy_through_simulate():
    system, coupling = _coupled_chain()
    scene = bd.Scene(bd.ConstrainedSystem(system, coupling), [GRAVITY])
    state = bd.State(
        jnp.eye(4),
        jnp.array([0.2, -0.1, 0.3]),
        jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]),
        jnp.array([0.5, -0.4, 0.3]),
    )
    first_coordinate, residual = _energy_kept_through_simulate(scene, state, coupling)
    assert np.ptp(first_coordinate) > 0.1  # the shape moves
    assert residual < 1e-15  # the full shape keeps the constraints


def test_a_coupling_sets_its_coordinates_and_reads_back_the_free_ones():
    _, coupling = _coupled_chain()
    p = jnp.array([0.4, -0.7, 1.1])
    q = coupling(p)
    np.testing.assert_array_equal(coupling.free_coordinates(q), p)
    x = 0.4 - 0.1
    np.testing.assert_allclose(q[2], 0.0 + 0.1 + 0.5 * x - 0.3 * x**2, rtol=1e-15)
    np.testing.assert_allclose(q[5], 0.2 + 0.05, rtol=1e-15)
    np.testing.assert_allclose(q[3], 0.3 - 0.8 * (-0.7 + 0.2), rtol=1e-15)
    np.testing.assert_allclose(coupling.residual(q), 0.0, atol=1e-16)
    assert float(jnp.max(jnp.abs(coupling.residual(q.at[3].add(0.01))))) == pytest.approx(0.01)


def test_couplings_refuse_what_they_cannot_solve():
    system = chain(3)
    with pytest.raises(ValueError, match="both set by a coupling and followed"):
        bd.JointCoupling(3, [(1, 0, (0.0, 1.0)), (2, 1, (0.0, 1.0))])
    with pytest.raises(ValueError, match="indices must lie"):
        bd.JointCoupling(3, [(3, 0, (0.0, 1.0))])
    with pytest.raises(ValueError, match="once"):
        bd.JointCoupling(3, [(1, 0, (0.0, 1.0)), (1, 2, (0.0, 1.0))])
    with pytest.raises(ValueError, match="at most 5"):
        bd.JointCoupling(3, [(1, 0, np.ones(6))])
    with pytest.raises(ValueError, match="has 3"):
        bd.ConstrainedSystem(system, bd.JointCoupling(4, [(1, 0, (0.0, 1.0))]))


def test_the_written_out_reverse_pass_covers_a_coupled_chain():
    # `StoredStepsAdjoint` (simulate's default for the Lie-group solvers) steps the field's
    # written-out reverse pass; on the pulled-back metric it equals autodiff of the field.
    from bundledyn._term import ReverseModeSceneTerm

    system, coupling = _coupled_chain()
    scene = bd.Scene(bd.ConstrainedSystem(system, coupling), [GRAVITY, bd.ShapeDamper(0.3)])
    k = jax.random.split(jax.random.PRNGKey(5), 4)
    g = bd.lie.se3_exp(jax.random.normal(k[0], (6,)))
    x = jax.random.normal(k[1], (3 + 6 + 3,))
    cotangent = (jax.random.normal(k[2], (6,)), jax.random.normal(k[3], (12,)))

    @jax.jit
    def pullbacks(g, x):
        def pullback(term):
            return jax.vjp(lambda g, x: term.body_vf(0.3, (g, x), None), g, x)[1](cotangent)

        return pullback(ReverseModeSceneTerm(scene)), pullback(bd.SceneTerm(scene))

    ours, reference = pullbacks(g, x)
    basis = jax.vmap(bd.lie.hat)(jnp.eye(6))  # a pose's cotangent, on its tangents g·ê_i
    on_tangents = [jnp.einsum("ab,ac,icb->i", ct, g, basis) for ct in (ours[0], reference[0])]
    np.testing.assert_allclose(on_tangents[0], on_tangents[1], rtol=0, atol=1e-11)
    scale = float(jnp.max(jnp.abs(reference[1])))
    np.testing.assert_allclose(ours[1], reference[1], rtol=0, atol=1e-11 * scale)


# --- MuJoCo's joint equalities ---------------------------------------------------------------

# A hand on a free palm: two fingers' slides coupled linearly (with an offset), a thumb's
# second hinge following its first by a quadratic (both with a reference position), and a
# wrist hinge held at an angle; springs and dampers on every joint.
GRIPPER = """<mujoco><option gravity="0 0 -9.81"/>
<default><joint damping="0.3" stiffness="2"/></default><worldbody><body name="palm">
<freejoint/><inertial pos="0 0 0" mass="1" diaginertia="0.1 0.12 0.08"/>
<body name="left" pos="0.1 0.05 0"><joint name="left" type="slide" axis="0 1 0"/>
<inertial pos="0.02 0 0" mass="0.1" diaginertia="0.01 0.01 0.01"/></body>
<body name="right" pos="0.1 -0.05 0"><joint name="right" type="slide" axis="0 1 0" ref="0.01"/>
<inertial pos="0.02 0 0" mass="0.1" diaginertia="0.01 0.01 0.01"/></body>
<body name="thumb" pos="0 0.08 0"><joint name="thumb1" type="hinge" axis="0 0 1" ref="0.2"/>
<inertial pos="0.03 0 0" mass="0.05" diaginertia="0.002 0.002 0.002"/>
<body name="tip" pos="0.06 0 0"><joint name="thumb2" type="hinge" axis="0 1 0" ref="-0.3"/>
<inertial pos="0.02 0 0" mass="0.03" diaginertia="0.001 0.001 0.001"/></body></body>
<body name="wrist" pos="-0.1 0 0"><joint name="wrist" type="hinge" axis="1 0 0"/>
<inertial pos="-0.03 0 0" mass="0.2" diaginertia="0.003 0.003 0.003"/></body>
</body></worldbody><equality>
<joint joint1="right" joint2="left" polycoef="0.002 -1 0 0 0"/>
<joint joint1="thumb2" joint2="thumb1" polycoef="0.1 0.5 -0.8 0 0"/>
<joint joint1="wrist" polycoef="0.3 0 0 0 0"/>
</equality></mujoco>"""


@pytest.fixture(scope="module")
def gripper():
    mujoco = pytest.importorskip("mujoco")
    with pytest.warns(UserWarning, match="reference position"):
        scene = bd.Scene.from_mjcf(GRIPPER, passive=True, gravity=True)
    model = mujoco.MjModel.from_xml_string(GRIPPER)
    return mujoco, model, scene


def _mujoco_equalities(mujoco, model, tree, q, qdot):
    """MuJoCo's equality rows at the full shape `q`: their violations and velocities, and
    its passive force on the joints."""
    state = bd.State(jnp.eye(4), q, jnp.zeros(6), qdot)
    qpos, qvel = (np.asarray(x) for x in bd.state_to_mujoco(tree, state, qpos0=model.qpos0))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    rows = np.asarray(data.efc_type) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    return data.efc_pos[rows], data.efc_vel[rows], np.array(data.qfrc_passive[6:])


def test_an_imported_models_joint_couplings_are_mujocos(gripper):
    mujoco, model, scene = gripper
    system = scene.system
    assert isinstance(system, bd.ConstrainedSystem) and system.shape_dim == 2  # left, thumb1
    coupling, tree = system.constraints, system.system
    key = jax.random.PRNGKey(11)

    @jax.jit  # one program for the three draws, not one per primitive
    def on_and_off(k):
        ka, kb = jax.random.split(k)
        p, pdot = 0.3 * jax.random.normal(ka, (2,)), jax.random.normal(kb, (2,))
        q, qdot = jax.jvp(coupling, (p,), (pdot,))
        off = q + 0.01 * jnp.arange(1.0, 6.0)
        return q, qdot, off, coupling.residual(off)

    for k in jax.random.split(key, 3):
        q, qdot, off, residual = on_and_off(k)
        violation, rate, _ = _mujoco_equalities(mujoco, model, tree, q, qdot)
        # MuJoCo finds its equalities kept, in position and velocity
        np.testing.assert_allclose(violation, 0.0, atol=1e-15)
        np.testing.assert_allclose(rate, 0.0, atol=1e-14)
        # off them, MuJoCo's violations are the coupling's residuals
        violation, _, _ = _mujoco_equalities(mujoco, model, tree, off, qdot)
        np.testing.assert_allclose(violation, residual, rtol=1e-12, atol=1e-15)


def test_an_imported_models_springs_and_dampers_act_on_its_full_shape(gripper):
    mujoco, model, scene = gripper
    coupling, tree = scene.system.constraints, scene.system.system
    p, pdot = jnp.array([0.02, 0.4]), jnp.array([0.3, -1.2])
    q, qdot = jax.jit(lambda p, pdot: jax.jvp(coupling, (p,), (pdot,)))(p, pdot)
    *_, passive = _mujoco_equalities(mujoco, model, tree, q, qdot)

    @jax.jit  # one program, not one per primitive
    def compared(p, pdot, passive):
        # the shape force on the free coordinates is J^T of MuJoCo's on the joints
        expected = jax.vjp(coupling, p)[1](passive)[0]
        shape_effects = [e for e in scene.effects if not isinstance(e, bd.Gravity)]
        kin = bd.Kinematics(0.0, jnp.eye(4), p, jnp.zeros(6), pdot)
        return sum(e.generalized_force(scene.system, kin)[1] for e in shape_effects), expected

    np.testing.assert_allclose(*compared(p, pdot, jnp.asarray(passive)), rtol=1e-12)


def test_states_of_a_coupled_model_go_to_mujoco_and_back(gripper):
    mujoco, model, scene = gripper
    system = scene.system
    g = bd.lie.se3_exp(jnp.array([0.3, -0.2, 0.5, 0.1, 0.2, -0.3]))
    state = bd.State(g, jnp.array([0.02, 0.4]), jnp.arange(1.0, 7.0), jnp.array([0.3, -1.2]))
    qpos, qvel = (np.asarray(x) for x in bd.state_to_mujoco(system, state, qpos0=model.qpos0))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    rows = np.asarray(data.efc_type) == int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    np.testing.assert_allclose(data.efc_pos[rows], 0.0, atol=1e-15)  # the couplings kept
    np.testing.assert_allclose(data.efc_vel[rows], 0.0, atol=1e-14)
    back = bd.state_from_mujoco(system, qpos, qvel, qpos0=model.qpos0)
    for a, b in zip(jax.tree.leaves(back), jax.tree.leaves(state), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)


def test_a_coupled_model_is_refused_as_a_bare_tree():
    pytest.importorskip("mujoco")
    # (warned of: the joints' springs left out, their reference positions)
    with pytest.warns(UserWarning), pytest.raises(ValueError, match="ConstrainedSystem"):
        bd.Multibody.from_mjcf(GRIPPER)
    weld = GRIPPER.replace(
        '<joint joint1="wrist" polycoef="0.3 0 0 0 0"/>', '<weld body1="wrist" body2="palm"/>'
    )
    with pytest.raises(ValueError, match="other than joint couplings"):
        bd.Scene.from_mjcf(weld)


# --- a closed loop: constraints given implicitly, solved by Newton's method ----------------

CRANK, COUPLER, ROCKER = 0.3, 1.0, 0.8
PIVOTS = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0]])  # on the base: A (crank), D (rocker)


def _about_z(angle, translation):
    T = np.eye(4)
    c, s = np.cos(angle), np.sin(angle)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = translation
    return T


def _bar(length, mass):
    """A thin bar along its frame's x axis from the origin."""
    return bd.RigidBody(
        mass, (length / 2, 0.0, 0.0), np.diag([1e-3, mass * length**2 / 12, mass * length**2 / 12])
    )


def _four_bar():
    """A free-floating four-bar linkage: the base is the ground link with pivots A and D,
    the crank AB, coupler BC and rocker CD hinged about the base's z axis, assembled with the
    crank upright and C above the base (one of the loop's two assembly modes). The loop
    closes where the rocker's tip is at D: two equations for the coupler's and the rocker's
    angles, the crank's free."""
    A, D = PIVOTS
    B = A + np.array([0.0, CRANK, 0.0])
    # C: on the circles about B and D (radii the coupler and the rocker), the upper one.
    gap = D - B
    distance = np.linalg.norm(gap)
    along = (COUPLER**2 - ROCKER**2 + distance**2) / (2 * distance)
    up = np.array([-gap[1], gap[0], 0.0]) / distance
    C = B + along * gap / distance + np.sqrt(COUPLER**2 - along**2) * up
    angles = [np.arctan2(*(b - a)[1::-1]) for a, b in ((A, B), (B, C), (C, D))]
    hinge = bd.Revolute((0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    links = [
        bd.Link(_bar(CRANK, 0.4), hinge, 0, _about_z(angles[0], A)),
        bd.Link(_bar(COUPLER, 1.1), hinge, 1, _about_z(angles[1] - angles[0], (CRANK, 0, 0))),
        bd.Link(_bar(ROCKER, 0.9), hinge, 2, _about_z(angles[2] - angles[1], (COUPLER, 0, 0))),
    ]
    system = bd.Multibody(
        bd.RigidBody(2.0, jnp.zeros(3), jnp.diag(jnp.array([0.01, 0.2, 0.2]))), links
    )
    tip = jnp.array([ROCKER, 0.0, 0.0, 1.0])

    def closure(q):
        return (system.body_poses(q)[3] @ tip)[:2] - D[:2]

    return system, bd.ImplicitConstraints(3, closure, dependent=(1, 2))


@eqx.filter_jit
def _solutions_and_derivatives(loop, p, h):
    """The solution at `p` and at `p ± h`, its first and second derivatives and those of the first
    at `p ± h` (one compiled program)."""
    first = lambda p: jax.jacfwd(loop)(p)[:, 0]
    return (
        loop(p), (loop(p + h), loop(p - h)), first(p), (first(p + h), first(p - h)),
        jax.jacfwd(first)(p)[:, 0],
    )  # fmt: skip


@eqx.filter_jit
def _residuals(loop, q, p_far):
    """The loop's residuals at its reference, at `q` and at its solution at `p_far` (one
    compiled program, not one per primitive)."""
    return loop.residual(jnp.zeros(3)), loop.residual(q), loop.residual(loop(p_far))


def test_a_closed_loop_is_assembled_and_solved_with_the_implicit_functions_derivatives():
    system, loop = _four_bar()
    h = 1e-6
    q, (above, below), first, (first_above, first_below), second = jax.tree.map(
        np.asarray, _solutions_and_derivatives(loop, jnp.array([0.4]), h)
    )
    # Far from the reference (the crank turned by 3 rad), on the same assembly mode.
    at_reference, at_q, far = (np.asarray(r) for r in _residuals(loop, q, jnp.array([3.0])))
    np.testing.assert_allclose(at_reference, 0.0, atol=1e-15)  # assembled
    assert float(q[0]) == 0.4 and float(np.max(np.abs(at_q))) < 1e-14
    assert float(np.min(np.abs(q[1:]))) > 0.05  # the coupler and the rocker turned
    np.testing.assert_allclose(first, (above - below) / (2 * h), rtol=1e-8)
    np.testing.assert_allclose(second, (first_above - first_below) / (2 * h), rtol=1e-6)
    assert float(np.max(np.abs(far))) < 1e-13


def test_a_closed_loop_moves_as_with_lagrange_multipliers():
    system, loop = _four_bar()
    for key in jax.random.split(jax.random.PRNGKey(11), 3):
        k = jax.random.split(key, 3)
        p = jax.random.uniform(k[0], (1,), minval=-0.5, maxval=0.5)
        xi = jax.random.normal(k[1], (6,))
        pdot = 2.0 * jax.random.normal(k[2], (1,))
        ours, reference = _both(system, loop, p, xi, pdot)
        for a, b in zip(ours, reference, strict=True):
            scale = float(jnp.max(jnp.abs(b)))
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-11 * scale)


def test_a_constraint_closing_over_a_parameter_is_differentiated_in_it():
    """f(q) = q₀² + q₁² - ρ², a plain function closing over ρ: under `jax.grad` in ρ the
    dependent q₁ = √(ρ² - q₀²) has the derivative ρ/√(ρ² - q₀²) (to 1e-12), the closed-over
    tracer carried as a leaf rather than frozen as a constant."""

    def height(radius, p):
        circle = lambda q: jnp.stack([q[0] ** 2 + q[1] ** 2 - radius**2])
        return bd.ImplicitConstraints(2, circle, dependent=(1,), reference=(0.0, 1.0))(p)[1]

    radius, p = jnp.array(1.3), jnp.array([0.5])
    derivative = jax.jit(jax.grad(height))(radius, p)
    np.testing.assert_allclose(derivative, radius / jnp.sqrt(radius**2 - p[0] ** 2), rtol=1e-12)


# Simulating differentiates the Newton solve twice (the pulled-back metric's jet): one of the
# slowest programs of the suite to compile.
@pytest.mark.slow
def test_a_closed_loop_keeps_its_energy_and_stays_closed_through_simulate():
    system, loop = _four_bar()
    scene = bd.Scene(bd.ConstrainedSystem(system, loop), [GRAVITY])
    state = bd.State(
        jnp.eye(4), jnp.array([0.1]), jnp.array([0.2, -0.3, 0.5, 0.1, 0.0, -0.2]), jnp.array([3.0])
    )
    crank, residual = _energy_kept_through_simulate(scene, state, loop)
    assert np.ptp(crank) > 1.0  # the crank turns
    assert residual < 1e-13


def test_implicit_constraints_refuse_what_they_cannot_solve():
    with pytest.raises(ValueError, match="must name coordinates"):
        bd.ImplicitConstraints(2, lambda q: q[1:], dependent=(2,))
    with pytest.raises(ValueError, match="each coordinate once"):
        bd.ImplicitConstraints(3, lambda q: q[1:], dependent=(1, 1))
    with pytest.raises(ValueError, match="one per dependent coordinate"):
        bd.ImplicitConstraints(3, lambda q: q, dependent=(1, 2))(jnp.array([0.1]))
    no_root = bd.ImplicitConstraints(2, lambda q: jnp.stack([q[1] ** 2 + 1.0]), dependent=(1,))
    with pytest.raises(Exception, match="did not solve"):
        no_root(jnp.array([0.3]))
