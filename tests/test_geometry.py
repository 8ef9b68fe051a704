"""Bundle geometry (issue: foundation): metric, locked inertia, connection, shape metric, curvature."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import (
    SYSTEMS,
    affine_body,
    asymmetric_body,
    body_inertia_data,
    chain,
    random_shapes,
    rigid_generic,
    tree4,
)
from traced import lowerings

import bundledyn as bd
from bundledyn import lie
from bundledyn._holonomy import curvature_by_holonomy

N_STATES = 32


@functools.cache
def geometry_batch(name):
    """One compiled, vmapped evaluation of every geometric quantity for one system."""
    system = SYSTEMS[name]()

    @jax.jit
    @jax.vmap
    def evaluate(q, xi, qdot):
        I_r = bd.locked_inertia(system, q)
        A = bd.connection(system, q)
        J = bd.shape_metric(system, q)
        U = bd.locked_velocity(system, q, xi, qdot)
        m, c, inertia = body_inertia_data(system, q)
        return dict(
            G=bd.metric(system, q),
            I_r=I_r,
            A=A,
            J=J,
            T=bd.kinetic_energy(system, q, xi, qdot),
            T_split=0.5 * U @ I_r @ U + 0.5 * qdot @ J @ qdot,
            m=m,
            c=c,
            inertia=inertia,
        )

    return system, evaluate


def sample(system, key, n=N_STATES):
    kq, kx, kd = jax.random.split(key, 3)
    q = random_shapes(system, kq, n)
    xi = jax.random.normal(kx, (n, 6))
    qdot = jax.random.normal(kd, (n, system.shape_dim))
    return q, xi, qdot


@pytest.mark.parametrize("name", SYSTEMS)
def test_kinetic_energy_split(name, key):
    """(2.1): T = ½ Uᵀ I_r U + ½ q̇ᵀ J_def q̇ equals ½ [ξ;q̇]ᵀ G [ξ;q̇]; G and J_def are SPD."""
    system, evaluate = geometry_batch(name)
    out = evaluate(*sample(system, key))
    np.testing.assert_allclose(out["T_split"], out["T"], rtol=1e-12)
    for M in (out["G"], out["J"]):
        if M.size == 0:
            continue
        np.testing.assert_allclose(M, jnp.swapaxes(M, 1, 2), atol=1e-12 * np.abs(M).max())
        assert np.all(np.linalg.eigvalsh(M) > 0)


@pytest.mark.parametrize("name", SYSTEMS)
def test_locked_inertia_has_theorem_2_3_form(name, key):
    """I_r(X, Y) = m X(c)·Y(c) + l(ω_X)·ω_Y with m, c, l summed independently body by body."""
    system, evaluate = geometry_batch(name)
    out = evaluate(*sample(system, key))
    m, c, inertia = out["m"], out["c"], out["inertia"]
    n = m.shape[0]
    # X ↦ (ω_X, X(c)) with X(c) = v_X + ω_X × c.
    P = jnp.zeros((n, 6, 6)).at[:, :3, :3].set(jnp.eye(3)).at[:, 3:, 3:].set(jnp.eye(3))
    P = P.at[:, 3:, :3].set(-lie.hat(c))
    D = (
        jnp.zeros((n, 6, 6))
        .at[:, :3, :3]
        .set(inertia)
        .at[:, 3:, 3:]
        .set(m[:, None, None] * jnp.eye(3)[None])
    )
    expected = jnp.einsum("nji,njk,nkl->nil", P, D, P)
    np.testing.assert_allclose(out["I_r"], expected, atol=1e-12 * np.abs(expected).max())


def _fd_body_momentum(system, q, xi, qdot, h=1e-3):
    """Total momentum in the section frame from finite-difference velocities, body by body."""

    def stencil(f):
        return (8 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12 * h)

    if isinstance(system, bd.AffineBody):
        from bundledyn._systems._affine_body import stretch

        def F(t):
            return lie.so3_exp(t * xi[:3]) @ stretch(q + t * qdot)

        Fdot, E = stencil(F), system.second_moment
        angular = lie.vee(Fdot @ E @ F(0.0).T - F(0.0) @ E @ Fdot.T)
        return jnp.concatenate([angular, system.mass * xi[3:]])

    def poses(t):
        return lie.se3_exp(t * xi) @ system.body_poses(q + t * qdot)

    r, rdot = poses(0.0), stencil(poses)
    nu = jax.vmap(lambda T, dT: lie.vee(lie.se3_inv(T) @ dT))(r, rdot)
    M = bd.spatial_inertia(system.mass, system.com, system.inertia)
    return jnp.einsum("nji,njk,nk->i", lie.Ad(lie.se3_inv(r)), M, nu)


@pytest.mark.parametrize("name", ["chain5", "tree4", "affine_body", "mjcf_chain5"])
def test_horizontal_motion_has_zero_momentum(name, key):
    """ξ = −A q̇ carries zero total momentum, summed independently over the bodies."""
    system = SYSTEMS[name]()
    q, _, qdot = sample(system, key, 4)

    @jax.jit
    @jax.vmap
    def momenta(q, qdot):
        xi = -bd.connection(system, q) @ qdot
        generic = _fd_body_momentum(system, q, jax.random.normal(key, (6,)), qdot)
        return _fd_body_momentum(system, q, xi, qdot), generic

    horizontal, generic = momenta(q, qdot)
    scale = np.abs(generic).max()
    assert scale > 1e-2  # a non-horizontal motion does carry momentum
    np.testing.assert_allclose(horizontal, 0.0, atol=1e-9 * scale)


@pytest.mark.parametrize("make", [lambda: chain(3), affine_body], ids=["chain3", "affine_body"])
def test_curvature_matches_small_loop_holonomy(make):
    """−log(holonomy)/ε² → curvature, the error shrinking like ε (seed 004 §2, structure eq.)."""
    system = make()
    q = 0.3 * jnp.ones(system.shape_dim) + 0.1 * jnp.arange(system.shape_dim, dtype=float)
    # Called on concrete values, the curvature is one compiled program (not one per primitive).
    Omega, programs = lowerings(bd.curvature, system, q)
    assert programs <= 1
    estimate = jax.jit(lambda eps: curvature_by_holonomy(system, q, eps))
    errors = np.array([np.abs(estimate(eps) - Omega).max() for eps in (1e-2, 5e-3, 2.5e-3)])
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 1.8) & (ratios < 2.2)), ratios
    assert errors[-1] < 1e-2 * np.abs(Omega).max()


@pytest.mark.parametrize("make", [lambda: chain(5), tree4], ids=["chain5", "tree4"])
def test_gauge_covariance(make, key):
    """Another body as section frame: J_def unchanged, curvature moved by Ad_{r_k⁻¹}."""
    system = make()
    q = random_shapes(system, key, 1)[0]
    sections = range(1, system.num_bodies)

    @jax.jit
    def in_every_gauge(q):
        r = system.body_poses(q)
        J, Omega = bd.shape_metric(system, q), bd.curvature(system, q)
        moved = [jnp.einsum("ij,jab->iab", lie.Ad(lie.se3_inv(r[k])), Omega) for k in sections]
        others = [system.with_section(k) for k in sections]
        return (
            J,
            Omega,
            jnp.stack(moved),
            jnp.stack([bd.shape_metric(o, q) for o in others]),
            jnp.stack([bd.curvature(o, q) for o in others]),
        )

    J, Omega, expected, J_other, Omega_other = in_every_gauge(q)
    np.testing.assert_allclose(J_other, jnp.broadcast_to(J, J_other.shape), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Omega_other, expected, atol=1e-10 * np.abs(Omega).max())
    assert not np.allclose(expected[-1], Omega, atol=1e-3)  # the gauge change is not trivial


def test_generic_system_reproduces_closed_forms(key):
    """User-given kinetic energies: the autodiff metric equals the closed forms."""
    np.testing.assert_allclose(
        bd.metric(rigid_generic(), jnp.zeros(0)), asymmetric_body().spatial_inertia(), rtol=1e-14
    )
    body = affine_body()
    from bundledyn._systems._affine_body import stretch

    def T(q, qdot, xi):  # ½ m |ċ|² + ½ tr(Ḟ E Ḟᵀ), Ḟ = R(ω̃U + U̇), written independently
        U, Udot = jax.jvp(stretch, (q,), (qdot,))
        Fdot = lie.hat(xi[:3]) @ U + Udot
        return 0.5 * body.mass * xi[3:] @ xi[3:] + 0.5 * jnp.trace(
            Fdot @ body.second_moment @ Fdot.T
        )

    generic = bd.GenericSystem(T, 6)
    q = random_shapes(body, key, 1)[0]
    np.testing.assert_allclose(bd.metric(body, q), bd.metric(generic, q), rtol=1e-12, atol=1e-14)


BAD_INPUTS = {
    "non-positive mass": (lambda: bd.RigidBody(0.0, np.zeros(3), np.eye(3)), "mass"),
    "NaN mass": (lambda: bd.RigidBody(np.nan, np.zeros(3), np.eye(3)), "mass"),
    "non-symmetric inertia": (
        lambda: bd.RigidBody(1.0, np.zeros(3), [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]),
        "symmetric",
    ),
    "indefinite inertia": (
        lambda: bd.RigidBody(1.0, np.zeros(3), np.diag([1.0, 1.0, -1.0])),
        "positive definite",
    ),
    "triangle inequality": (
        lambda: bd.RigidBody(1.0, np.zeros(3), np.diag([1.0, 1.0, 3.0])),
        "triangle",
    ),
    "com shape": (lambda: bd.RigidBody(1.0, np.zeros(2), np.eye(3)), "com"),
    "unknown joint": (
        lambda: bd.Link(asymmetric_body(), "hinge", 0),
        "unknown joint type",
    ),
    "zero axis": (lambda: bd.Revolute(np.zeros(3)), "axis"),
    "parallel universal": (lambda: bd.Universal([1, 0, 0], [2, 0, 0]), "parallel"),
    "parent order": (
        lambda: bd.Multibody(asymmetric_body(), [bd.Link(asymmetric_body(), bd.Fixed(), 1)]),
        "parent",
    ),
    "bad placement": (
        lambda: bd.Link(asymmetric_body(), bd.Fixed(), 0, 2 * np.eye(4)),
        "rigid transform",
    ),
    "affine second moment": (
        lambda: bd.AffineBody(1.0, np.diag([1.0, -1.0, 1.0])),
        "second_moment",
    ),
    "affine mass": (lambda: bd.AffineBody(-1.0, np.eye(3)), "mass"),
    "generic not callable": (lambda: bd.GenericSystem(3.0, 0), "callable"),
}


@pytest.mark.parametrize("case", BAD_INPUTS)
def test_bad_inputs_raise_clear_errors(case):
    make, match = BAD_INPUTS[case]
    with pytest.raises(ValueError, match=match):
        make()


GEOMETRY_FUNCTIONS = {
    "metric": lambda s, q: bd.metric(s, q),
    "locked_inertia": lambda s, q: bd.locked_inertia(s, q),
    "connection": lambda s, q: bd.connection(s, q),
    "shape_metric": lambda s, q: bd.shape_metric(s, q),
    "curvature": lambda s, q: bd.curvature(s, q),
    "kinetic_energy": lambda s, q: bd.kinetic_energy(s, q, jnp.ones(6), jnp.ones(s.shape_dim)),
    "locked_velocity": lambda s, q: bd.locked_velocity(s, q, jnp.ones(6), jnp.ones(s.shape_dim)),
}


@pytest.mark.parametrize("fn", GEOMETRY_FUNCTIONS)
def test_geometry_under_jit_vmap_grad(fn, key):
    """Every public geometry function jits, vmaps over q, and has correct gradients in q and mass."""
    f = GEOMETRY_FUNCTIONS[fn]
    system = chain(3)
    qs = random_shapes(system, key, 3)
    batched = jax.jit(jax.vmap(lambda q: f(system, q)))(qs)
    np.testing.assert_allclose(batched[1], f(system, qs[1]), rtol=1e-12, atol=1e-14)

    weights = jax.random.normal(key, batched.shape[1:])

    @jax.jit
    def loss(q, mass):
        return jnp.sum(weights * f(eqx.tree_at(lambda s: s.mass, system, mass), q))

    q, mass = qs[0], system.mass
    grad_q, grad_mass = jax.jit(jax.grad(loss, argnums=(0, 1)))(q, mass)
    h = 1e-6
    central = jax.jit(
        jax.vmap(lambda dq, dm: (loss(q + dq, mass + dm) - loss(q - dq, mass - dm)) / (2 * h))
    )
    Eq, Em = h * jnp.eye(q.shape[0]), h * jnp.eye(mass.shape[0])
    fd_q = central(Eq, jnp.zeros((q.shape[0], mass.shape[0])))
    fd_mass = central(jnp.zeros((mass.shape[0], q.shape[0])), Em)
    np.testing.assert_allclose(grad_q, fd_q, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(grad_mass, fd_mass, rtol=1e-6, atol=1e-7)


def test_screw_derivatives_are_along_unit_screws(key):
    """Derivatives in `Multibody.screw_axes` are those of the model whose screws stay unit:
    the metric (kinematics and joint columns) along a random direction equals central
    differences of the metric with the perturbed screws renormalized (rotation axes to
    $|\\omega| = 1$, a translation's $\\omega$ to 0), and reverse mode is its transpose."""
    system = chain(6)  # revolute, universal, spherical, revolute and prismatic joints
    S = system.screw_axes
    rotation = np.linalg.norm(np.asarray(S[:, :3]), axis=1, keepdims=True) > 0
    assert rotation.any() and not rotation.all()

    def unit(S):
        w = S[:, :3]
        w = jnp.where(rotation, w / jnp.linalg.norm(w, axis=1, keepdims=True), 0.0)
        return jnp.concatenate([w, S[:, 3:]], axis=1)

    q = random_shapes(system, key, 1)[0]
    metric = jax.jit(lambda S: eqx.tree_at(lambda s: s.screw_axes, system, S).metric(q))
    dS = jax.random.normal(jax.random.fold_in(key, 1), S.shape)
    W = jax.random.normal(jax.random.fold_in(key, 2), (6 + q.shape[0],) * 2)
    _, tangent = jax.jvp(metric, (S,), (dS,))
    h = 1e-6
    central = (metric(unit(S + h * dS)) - metric(unit(S - h * dS))) / (2 * h)
    np.testing.assert_allclose(tangent, central, atol=1e-7 * float(jnp.abs(central).max()))
    grad = jax.grad(lambda S: jnp.sum(W * metric(S)))(S)
    np.testing.assert_allclose(jnp.sum(grad * dS), jnp.sum(W * tangent), rtol=1e-12)


@pytest.mark.parametrize("name", SYSTEMS)
def test_metric_derivative_equals_autodiff_of_the_metric(name, key):
    """`metric_and_derivative` and the contractions of `metric_jet` (closed forms for trees
    of bodies) equal jacfwd of `metric`: the derivative along $u$, alone and applied to
    velocities, the forms $x^T\\partial_k G\\,y$ and their derivative along $u$."""
    system = SYSTEMS[name]()
    d = system.shape_dim

    @jax.jit
    @jax.vmap
    def both(q, u, x, y):
        jet = system.metric_jet(q)
        G_ad, dG_ad = bd.AbstractSystem.metric_and_derivative(system, q)
        closed = (
            *system.metric_and_derivative(q),
            jet.along(u),
            jet.along_applied(u, jnp.stack([x, y])),
            jet.forms(jnp.stack([x, y]))[0, 1],
            jet.forms_along(u, jnp.stack([x, y]), jax.linearize(system.metric_jet, q)[1])[0, 1],
        )
        dG_u = jnp.tensordot(u, dG_ad, 1)
        ddG_u = jax.jvp(
            lambda q: bd.AbstractSystem.metric_and_derivative(system, q)[1], (q,), (u,)
        )[1]
        autodiff = (
            G_ad,
            dG_ad,
            dG_u,
            jnp.stack([dG_u @ x, dG_u @ y]),
            jnp.einsum("i,kij,j->k", x, dG_ad, y),
            jnp.einsum("i,kij,j->k", x, ddG_u, y),
        )
        return closed, autodiff

    k = jax.random.split(key, 4)
    args = (
        random_shapes(system, k[0], 16),
        jax.random.normal(k[1], (16, d)),
        jax.random.normal(k[2], (16, 6 + d)),
        jax.random.normal(k[3], (16, 6 + d)),
    )
    closed, autodiff = both(*args)
    for value, expected in zip(closed, autodiff, strict=True):
        scale = max(np.abs(expected).max(initial=0.0), 1.0)
        np.testing.assert_allclose(value, expected, rtol=0, atol=1e-12 * scale)


@jax.jit
def _stretch_derivatives_both_ways(q):
    from bundledyn._systems._affine_body import (
        _stretch_third_derivatives,
        stretch,
        stretch_derivatives,
    )

    by_autodiff, derivative = [], stretch
    for _ in range(4):
        by_autodiff.append(derivative(q))
        derivative = jax.jacfwd(derivative)
    return (*stretch_derivatives(q), _stretch_third_derivatives(q)), by_autodiff


def test_affine_stretch_derivatives_where_eigenvalues_repeat():
    """The Daleckii–Krein derivatives of U = exp(sym q) (the closed-form affine metric jet, and
    the third ones its gradients use) equal autodiff of `expm` where sym q has three equal
    eigenvalues (q = 0, the undeformed body), two, or none: to 1e-14 relative, the third
    derivatives to 1e-13 (measured 5.7e-14 with two equal eigenvalues)."""
    for q in (
        [0.0] * 6,
        [0.2, 0.2, 0.2, 0, 0, 0],
        [0.2, 0.2, 0.5, 0, 0, 0],
        [1.2, -0.8, 2, 0.4, -1.6, 1],
    ):
        closed, by_autodiff = _stretch_derivatives_both_ways(jnp.array(q))
        for a, b, tol in zip(closed, by_autodiff, (1e-14, 1e-14, 1e-14, 1e-13), strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=tol * np.abs(b).max())


def test_affine_fourth_stretch_derivatives_against_autodiff():
    """The fourth derivatives of U = exp(sym q) (the tangent of the third, reached by a
    Hessian of the vector field) by Daleckii–Krein equal autodiff of `expm` four times, to
    1e-14 relative, where sym q has three, two or no equal eigenvalues. The repeated ones
    are taken at ‖sym q‖∞ ≤ 1/4, where `expm` needs no squaring: autodiff through its
    squarings loses ~1e-12 in fourth derivatives (at 0.2·(1, 1, 1, 0, 0, 0) Daleckii–Krein
    is within 2e-15 of the closed form e^0.2/4! Σ_σ E_σ₁E_σ₂E_σ₃E_σ₄ and autodiff 1.2e-12)."""
    from bundledyn._systems._affine_body import _stretch_fourth_derivatives, stretch

    by_autodiff = jax.jit(jax.jacfwd(jax.jacfwd(jax.jacfwd(jax.jacfwd(stretch)))))
    closed = jax.jit(_stretch_fourth_derivatives)
    for q in (
        [0.0] * 6,
        [0.05, 0.05, 0.05, 0, 0, 0],
        [0.05, 0.05, 0.1, 0, 0, 0],
        [1.2, -0.8, 2, 0.4, -1.6, 1],
    ):
        expected = by_autodiff(jnp.array(q))
        np.testing.assert_allclose(
            closed(jnp.array(q)), expected, rtol=0, atol=1e-14 * np.abs(expected).max()
        )
