"""Lie-group ODE solvers (LieEuler, RKMK4, RKMK54, RKMK87) inside diffrax.

One vector field serves two test problems, selected by `args = (k, c, d, amp)`:

- `rigid` (args = 0): a torque-free rigid body, inertia diag(1, 2, 3), mass 1.5;
  y = (g, x), x = (ω, v) body velocities, ξ = (ω, v), I ω̇ = (Iω)×ω, v̇ = v×ω. The spatial
  momentum (R I ω + p × m R v, m R v) and the energy are invariants.
- `coupled`: the same plus time dependence in ξ, a torque depending on R, damping and a
  force depending on the translation p — every stage sees t, g and x.

Because the problem is selected by traced `args`, each jitted solve compiles once for both
problems; compile time is the budget here. References come from scipy's DOP853 on the
embedded system (rtol = atol = 1e-13), independent of diffrax and of the Lie solvers.
"""

import functools
import itertools
import math
import re

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
import scipy.integrate
from registry import RK_SOLVERS, RKMK87_STEP_STAGES_ONLY
from traced import scan_lengths

from bundledyn import AbstractBodyTerm, lie
from bundledyn._solver._lie_euler import LieEuler
from bundledyn._solver._rkmk import RKMK54, RKMK87
from bundledyn._solver._tableau import (
    LieButcherTableau,
    dopri5_tableau,
    dopri8_tableau,
    euler_tableau,
    rk4_tableau,
)

T1 = 2.0
INERTIA = np.array([1.0, 2.0, 3.0])
MASS = 1.5
PROBLEMS = {"rigid": np.zeros(4), "coupled": np.array([0.8, 0.1, 0.5, 0.3])}
TS = np.linspace(0.13, T1 - 0.11, 7)  # SaveAt(ts=...) times, generically between steps
MAX_STEPS = 2048
ORTHO_TOL = 1e-13


def body_vector_field(t, y, args):
    """The field left-trivialized: `(xi, xdot)` with ġ = g ξ̂."""
    g, x = y
    k, c, d, amp = args
    R, p = g[:3, :3], g[:3, 3]
    w, v = x[:3], x[3:]
    ez = jnp.array([0.0, 0.0, 1.0])
    xi = jnp.concatenate(
        [w + amp * jnp.sin(2 * t) * ez, v + amp * jnp.cos(t) * jnp.array([0.0, 1.0, 0.0])]
    )
    wdot = jnp.cross(INERTIA * w, w) / INERTIA + k * jnp.cross(R[2, :], ez) - c * w
    vdot = jnp.cross(v, w) - d * p[2] * ez + amp * jnp.sin(t) * jnp.array([1.0, 0.0, 0.0])
    return xi, jnp.concatenate([wdot, vdot])


def vector_field(t, y, args):
    xi, xdot = body_vector_field(t, y, args)
    return y[0] @ lie.hat(xi), xdot


TERM = diffrax.ODETerm(vector_field)
G0 = np.asarray(lie.se3_exp(jnp.array([0.3, -0.2, 0.5, 1.0, 0.2, -0.4])))
X0 = np.array([0.4, 2.0, -0.3, 0.5, -1.0, 0.3])
Y0 = (G0, X0)

# ----------------------------------------------------------------------------- helpers

TRACES = {"solve": 0}


@eqx.filter_jit
def _solve(solver, controller, saveat, y0, args, t0, t1, dt0):
    TRACES["solve"] += 1
    return diffrax.diffeqsolve(
        TERM,
        solver,
        t0,
        t1,
        dt0,
        y0,
        args,
        saveat=saveat,
        stepsize_controller=controller,
        max_steps=MAX_STEPS,
        throw=False,
    )


def _f64(a):
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype=jnp.float64), a)


def solve(solver, controller, args, y0=Y0, t0=0.0, t1=T1, dt0=None, ts=None):
    """One compiled solve per (solver, controller type). ys = (y(t1), y at steps, y at ts);
    dense output (sol.evaluate) with adaptive steps."""
    ts = (TS if t1 > t0 else TS[::-1]) if ts is None else ts
    saveat = diffrax.SaveAt(
        subs=[
            diffrax.SubSaveAt(t1=True),
            diffrax.SubSaveAt(steps=True),
            diffrax.SubSaveAt(ts=_f64(ts)),
        ],
        dense=isinstance(controller, diffrax.PIDController),
    )
    dt0 = None if dt0 is None else _f64(dt0)
    return _solve(solver, controller, saveat, _f64(y0), _f64(args), _f64(t0), _f64(t1), dt0)


def pid(rtol):
    return diffrax.PIDController(rtol=_f64(rtol), atol=_f64(rtol))


def final(sol):
    return jax.tree.map(lambda a: np.asarray(a[0]), sol.ys[0])


def at_steps(sol):
    n = int(sol.stats["num_accepted_steps"])
    return np.asarray(sol.ts[1][:n]), jax.tree.map(lambda a: np.asarray(a[:n]), sol.ys[1])


evaluate = eqx.filter_jit(jax.vmap(lambda sol, t: sol.evaluate(t), in_axes=(None, 0)))

_vf_flat = jax.jit(
    lambda t, z, args: jnp.concatenate(
        [a.ravel() for a in vector_field(t, (z[:16].reshape(4, 4), z[16:]), args)]
    )
)


def reference(args, ts, y0=Y0, event=None):
    """scipy DOP853 on the embedded system: (y at ts, scipy result)."""
    z0 = np.concatenate([np.asarray(y0[0]).ravel(), np.asarray(y0[1])])
    args = jnp.asarray(args)
    res = scipy.integrate.solve_ivp(
        lambda t, z: np.asarray(_vf_flat(t, z, args)),
        (0.0, T1),
        z0,
        method="DOP853",
        t_eval=np.asarray(ts),
        rtol=1e-13,
        atol=1e-13,
        events=event,
    )
    z = res.y.T if len(ts) else np.zeros((0, 22))
    return (z[:, :16].reshape(-1, 4, 4), z[:, 16:]), res


@jax.jit
def _log_error(g, g_ref):
    return jnp.abs(lie.se3_log(lie.se3_inv(g_ref) @ g)).max()


def error(y, y_ref):
    """max over times of |log(g_ref⁻¹ g)| and |x - x_ref| (leading time axes allowed)."""
    g, g_ref = (np.asarray(a).reshape(-1, 4, 4) for a in (y[0], y_ref[0]))
    x, x_ref = (np.asarray(a).reshape(len(g), -1) for a in (y[1], y_ref[1]))
    e_g = max(float(_log_error(gi, gr)) for gi, gr in zip(g, g_ref, strict=True))
    return max(e_g, float(np.abs(x - x_ref).max()))


def orthogonality_error(g):
    """max |RᵀR - 1| over the finite poses of a stack; also checks the bottom row exactly."""
    g = np.asarray(g).reshape(-1, 4, 4)
    g = g[np.all(np.isfinite(g), axis=(1, 2))]
    assert len(g) > 0
    np.testing.assert_array_equal(g[:, 3, :], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (len(g), 4)))
    R = g[:, :3, :3]
    return float(np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max())


def momentum(y):
    g, x = y
    R, p = g[..., :3, :3], g[..., :3, 3]
    P = MASS * np.einsum("...ij,...j->...i", R, x[..., 3:])
    L = np.einsum("...ij,...j->...i", R, INERTIA * x[..., :3]) + np.cross(p, P)
    return np.concatenate([L, P], axis=-1)


def energy(y):
    x = y[1]
    return 0.5 * np.sum(INERTIA * x[..., :3] ** 2, -1) + 0.5 * MASS * np.sum(x[..., 3:] ** 2, -1)


_REF = {}


def reference_ts_t1(problem):
    """Reference at (TS, T1), cached."""
    if problem not in _REF:
        (g, x), _ = reference(PROBLEMS[problem], np.append(TS, T1))
        _REF[problem] = (g[:-1], x[:-1]), (g[-1], x[-1])
    return _REF[problem]


# --------------------------------------------------------------------------- tableaus


@functools.cache
def rooted_trees(n):
    """The rooted trees with n vertices, each a sorted tuple of its subtrees."""
    if n == 1:
        return ((),)

    def partitions(m, largest):
        if m == 0:
            yield ()
        for p in range(min(m, largest), 0, -1):
            for rest in partitions(m - p, p):
                yield (p, *rest)

    trees = {
        tuple(sorted(children))
        for sizes in partitions(n - 1, n - 1)
        for children in itertools.product(*(rooted_trees(p) for p in sizes))
    }
    return tuple(sorted(trees))


def _phi(tree, a):
    """Φ(τ) per stage: the product over the subtrees σ of a Φ(σ)."""
    out = np.ones(a.shape[0])
    for child in tree:
        out = out * (a @ _phi(child, a))
    return out


def _size(tree):
    return 1 + sum(_size(child) for child in tree)


def _gamma(tree):
    """γ(τ) = |τ| Π_σ γ(σ) over the subtrees σ."""
    return _size(tree) * math.prod(_gamma(child) for child in tree)


def order_residual(weights, tab, n, theta=1.0):
    """max over rooted trees τ with n vertices of |w(θ)·Φ(τ) - θⁿ/γ(τ)| (weights (θ, s))."""
    theta = np.atleast_1d(theta)
    weights = np.atleast_2d(weights)
    return max(
        float(np.abs(weights @ _phi(tree, tab.a) - theta**n / _gamma(tree)).max())
        for tree in rooted_trees(n)
    )


def test_tableaus():
    assert [len(rooted_trees(n)) for n in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]
    for tab, ref in [
        (dopri5_tableau, diffrax.Dopri5.tableau),
        (dopri8_tableau, diffrax.Dopri8.tableau),
    ]:
        for a, b in zip(tab.a_lower, ref.a_lower, strict=True):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(tab.b_sol, ref.b_sol)
        np.testing.assert_allclose(tab.b_error, ref.b_error, rtol=0, atol=1e-16)
        np.testing.assert_array_equal(tab.c, ref.c)
    assert dopri5_tableau.fsal and dopri8_tableau.fsal
    assert not rk4_tableau.fsal and not euler_tableau.fsal
    assert dopri8_tableau.num_stages == 14 and dopri8_tableau.dense.shape == (6, 14)
    theta = np.linspace(0.0, 1.0, 11)
    # The propagated solution has the tableau's order: b·Φ(τ) = 1/γ(τ) for |τ| ≤ p.
    for tab, order in [(euler_tableau, 1), (rk4_tableau, 4), (dopri5_tableau, 5)]:
        for n in range(1, order + 1):
            assert order_residual(tab.b_sol, tab, n) < 1e-14, (order, n)
    for n in range(1, 9):
        assert order_residual(dopri8_tableau.b_sol, dopri8_tableau, n) < 1e-14, n
    # The θ⁶ row of Dopri8's dense output is corrected by ≤ 1e-12 so that b_i(1) = b_i
    # (see `_dopri8`); otherwise it is diffrax's y0 + Σ_i θ polyval(E_i, θ) k_i.
    eval_coeffs = np.asarray(diffrax.Dopri8.interpolation_cls.eval_coeffs)
    diffrax_bt = theta[:, None] * np.stack([np.polyval(e, theta) for e in eval_coeffs], -1)
    powers = theta[:, None] ** np.arange(1, 7)
    np.testing.assert_allclose(powers @ dopri8_tableau.dense, diffrax_bt, rtol=0, atol=2e-12)
    # Continuous extensions: b_i(θ) = Σ_m B[m-1, i] θ^m must satisfy the order conditions
    # of their dense order at every θ, and not those of the next order. Dopri8's sextic
    # (in diffrax: "8th order interpolation") is of fifth order only.
    for tab, order in [(rk4_tableau, 3), (dopri5_tableau, 4), (dopri8_tableau, 5)]:
        powers = theta[:, None] ** np.arange(1, tab.dense.shape[0] + 1)
        bt = powers @ tab.dense  # (θ, s)
        np.testing.assert_allclose(bt[-1], tab.b_sol, rtol=0, atol=1e-14)
        for n in range(1, order + 1):
            assert order_residual(bt, tab, n, theta) < 1e-13, (order, n)
        assert order_residual(bt, tab, order + 1, theta) > 1e-6, order


# Heun's method with the Euler step as its embedded solution and a quadratic dense output.
HEUN = dict(
    a_lower=(np.array([1.0]),),
    b_sol=np.array([0.5, 0.5]),
    c=np.array([1.0]),
    dense=np.array([[1.0, 0.0], [-0.5, 0.5]]),
    b_error=np.array([-0.5, 0.5]),
)


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(c=np.array([0.9])), "row-sum condition Σ_j a_2j = c_2 of stage 2: the residual "
         "Σ_j a_2j - c_2 is 0.1"),
        (dict(b_sol=np.array([0.5, 0.6]), dense=np.array([[1.0, 0.0], [-0.5, 0.6]])),
         "first-order condition Σ_i b_i = 1: the residual Σ_i b_i - 1 is 0.1"),
        (dict(dense=np.array([[1.0, 0.0], [-0.5, 0.6]])),
         "end condition b_i(1) = b_i, b_i(1) = Σ_m B_m-1,i: the residual b_2(1) - b_2 is 0.1"),
        (dict(b_error=np.array([-0.5, 0.6])),
         "embedded solution's first-order condition Σ_i (b_i - b̂_i) = 0: the residual "
         "Σ_i (b_i - b̂_i) is 0.1"),
        (dict(c=np.array([1.0, 1.0])), "`c` must hold the 1 nodes"),
        (dict(a_lower=(np.array([1.0, 0.0]),)), "row 2 of `a_lower` (stage 2) must have 1 entries"),
        (dict(dense=np.array([1.0, 0.0])), "`dense` must have shape (degree, 2)"),
        (dict(b_error=np.array([0.0])), "`b_error` must have shape (2,)"),
    ],
    ids=["row-sum", "weights", "dense-end", "error-weights", "nodes", "row", "dense", "error"],
)  # fmt: skip
def test_a_tableau_that_breaks_an_order_condition_is_refused(change, message):
    """Each order condition every tableau meets, and each shape, is checked at construction,
    with the condition and its residual in the message; Heun's tableau itself passes."""
    heun = LieButcherTableau(**HEUN)
    assert heun.num_stages == 2 and heun.step_stages == 2 and not heun.fsal
    with pytest.raises(ValueError, match=re.escape(message)):
        LieButcherTableau(**{**HEUN, **change})


# --------------------------------------------------------------------------- accuracy

FIXED = {
    "LieEuler": (RK_SOLVERS["LieEuler"], 1, [64, 128, 256, 512]),
    "RKMK4": (RK_SOLVERS["RKMK4"], 4, [8, 16, 32, 64]),
    "RKMK54": (RK_SOLVERS["RKMK54"], 5, [12, 18, 27, 40]),
    # Errors 2e-7 ... 3e-11; the slope approaches 8 from below (7.85 rigid, 7.96 coupled).
    "RKMK87": (RK_SOLVERS["RKMK87"], 8, [6, 8, 11, 16]),
}


@pytest.mark.parametrize("problem", list(PROBLEMS))
@pytest.mark.parametrize("name", list(FIXED))
def test_convergence_order(name, problem):
    solver, order, ns = FIXED[name]
    _, y_ref = reference_ts_t1(problem)
    errors = []
    for n in ns:
        sol = solve(solver, diffrax.ConstantStepSize(), PROBLEMS[problem], dt0=T1 / n)
        assert sol.result == diffrax.RESULTS.successful
        assert int(sol.stats["num_accepted_steps"]) == n
        errors.append(error(final(sol), y_ref))
    slope = np.polyfit(np.log(T1 / np.array(ns)), np.log(errors), 1)[0]
    print(f"{name} {problem}: errors {errors}, order {slope:.2f}")
    assert abs(slope - order) < 0.3, (errors, slope)


@pytest.mark.parametrize("problem", list(PROBLEMS))
def test_adaptive_tolerance(problem):
    _, y_ref = reference_ts_t1(problem)
    errors, accepted = [], []
    for rtol in [1e-6, 1e-8, 1e-10]:
        sol = solve(RKMK54(), pid(rtol), PROBLEMS[problem])
        assert sol.result == diffrax.RESULTS.successful
        stats = {k: int(v) for k, v in sol.stats.items()}
        assert stats["num_steps"] == stats["num_accepted_steps"] + stats["num_rejected_steps"]
        assert 0 <= stats["num_rejected_steps"] < stats["num_accepted_steps"] // 2 + 3
        assert 5 < stats["num_accepted_steps"] < 500
        errors.append(error(final(sol), y_ref))
        accepted.append(stats["num_accepted_steps"])
        # Global error ~10 rtol, as for diffrax.Dopri5 on the embedded system (measured:
        # 0.7-1.4x its error, with ~10% fewer steps).
        assert errors[-1] < 15 * rtol, (rtol, errors[-1])
        assert orthogonality_error(at_steps(sol)[1][0]) <= ORTHO_TOL
    print(f"{problem}: errors {errors}, steps {accepted}")
    assert errors[0] > errors[1] > errors[2]
    assert accepted[0] < accepted[1] < accepted[2]


@pytest.mark.parametrize("problem", list(PROBLEMS))
def test_rkmk87_fewer_steps(problem):
    """At a tight tolerance the eighth-order pair meets it in far fewer steps, and field
    evaluations, than RKMK54: what RKMK87 is for. Measured (rigid, coupled) at rtol 1e-10:
    13, 16 accepted steps against 74, 81; errors 1.6e-10 against 7.7e-10, 1.0e-9."""
    rtol = 1e-10
    _, y_ref = reference_ts_t1(problem)
    steps, evaluations, errors = {}, {}, {}
    for solver in [RKMK54(), RKMK87()]:
        name = type(solver).__name__
        sol = solve(solver, pid(rtol), PROBLEMS[problem])
        assert sol.result == diffrax.RESULTS.successful
        steps[name] = int(sol.stats["num_accepted_steps"])
        evaluations[name] = int(sol.stats["num_steps"]) * solver.tableau.num_stages
        errors[name] = error(final(sol), y_ref)
        assert orthogonality_error(at_steps(sol)[1][0]) <= ORTHO_TOL
    print(f"{problem}: steps {steps}, evaluations {evaluations}, errors {errors}")
    assert errors["RKMK87"] < 3 * rtol and errors["RKMK87"] < errors["RKMK54"]
    assert 3 * steps["RKMK87"] < steps["RKMK54"]
    assert 2 * evaluations["RKMK87"] < evaluations["RKMK54"]


def _step_scan_lengths(solver, args):
    """Lengths of the `lax.scan`s in one traced step: the stage loop's is the stage count."""
    return scan_lengths(lambda y: solver.step(TERM, 0.0, 0.1, y, args, None, False), _f64(Y0))


def test_dense_output_off_skips_the_dense_only_stage():
    """`RKMK87(dense_output=False)` evaluates 13 stages instead of 14 (the 14th enters
    neither the solution nor the error estimate), takes the same steps to the same states,
    and its dense output is NaN rather than silently wrong."""
    args = PROBLEMS["coupled"]
    assert _step_scan_lengths(RKMK87(), _f64(args)) == {14}
    assert _step_scan_lengths(RKMK87_STEP_STAGES_ONLY, _f64(args)) == {13}
    with_dense = solve(RKMK87(), pid(1e-8), args)
    without = solve(RKMK87_STEP_STAGES_ONLY, pid(1e-8), args)
    for a, b in zip(at_steps(with_dense), at_steps(without), strict=True):
        for leaf_a, leaf_b in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
            np.testing.assert_array_equal(leaf_a, leaf_b)
    assert all(np.all(np.isnan(leaf)) for leaf in jax.tree.leaves(without.ys[2]))
    assert all(np.all(np.isfinite(leaf)) for leaf in jax.tree.leaves(with_dense.ys[2]))


def test_rigid_body_invariants():
    sol = solve(RKMK54(), pid(1e-12), PROBLEMS["rigid"])
    _, ys = at_steps(sol)
    assert len(ys[0]) > 20
    np.testing.assert_allclose(
        momentum(ys), np.broadcast_to(momentum(Y0), (len(ys[0]), 6)), atol=1e-10
    )
    np.testing.assert_allclose(energy(ys), energy(Y0), atol=1e-10)
    assert orthogonality_error(ys[0]) <= ORTHO_TOL


ON_GROUP = {  # name -> (solver, [(controller, dt0)], error of the dense output beyond 10x)
    "LieEuler": (
        RK_SOLVERS["LieEuler"],
        [(diffrax.ConstantStepSize(), 0.25), (diffrax.ConstantStepSize(), 1e-3)],
        1e-11,
    ),
    "RKMK4": (
        RK_SOLVERS["RKMK4"],
        [(diffrax.ConstantStepSize(), 0.5), (diffrax.ConstantStepSize(), 4e-3)],
        1e-11,
    ),
    "RKMK54": (RK_SOLVERS["RKMK54"], [(pid(1e-3), None), (pid(1e-12), None)], 1e-11),
    # Fifth-order dense output over eighth-order steps: at pid(1e-12) SaveAt(ts) is 3e-10
    # off where the steps are 1.5e-12 off (diffrax.Dopri8 on the embedded system alike).
    "RKMK87": (RK_SOLVERS["RKMK87"], [(pid(1e-3), None), (pid(1e-12), None)], 1e-9),
}


@pytest.mark.parametrize("name", list(ON_GROUP))
def test_stays_on_group(name):
    """Orthogonal to 1e-13 at every step, at SaveAt(ts), and in the dense output between
    steps, for loose and tight settings; the dense output is as accurate as the steps (to
    within its own, lower, order for RKMK87)."""
    solver, cases, dense_slack = ON_GROUP[name]
    rng = np.random.default_rng(0)
    for problem, args in PROBLEMS.items():
        y_ts_ref, y_t1_ref = reference_ts_t1(problem)
        for controller, dt0 in cases:
            sol = solve(solver, controller, args, dt0=dt0)
            assert sol.result == diffrax.RESULTS.successful
            poses = [sol.ys[0][0], at_steps(sol)[1][0], sol.ys[2][0]]
            if sol.interpolation is not None:  # SaveAt(dense=True), with adaptive steps
                poses.append(evaluate(sol, jnp.asarray(rng.uniform(0.0, T1, 20)))[0])
            for g in poses:
                assert orthogonality_error(g) <= ORTHO_TOL
            e_ts = error(sol.ys[2], y_ts_ref)
            e_t1 = error(final(sol), y_t1_ref)
            print(f"{name} {problem} {dt0}: error at ts {e_ts:.2e}, at t1 {e_t1:.2e}")
            assert e_ts < 10 * e_t1 + dense_slack


def test_dense_output():
    """SaveAt(dense=True) + sol.evaluate: on the group, accurate, consistent with the steps
    and with SaveAt(ts=...)."""
    args = PROBLEMS["coupled"]
    sol = solve(RKMK54(), pid(1e-8), args)
    t_steps, y_steps = at_steps(sol)
    t_dense = np.sort(np.random.default_rng(1).uniform(0.0, T1, 40))
    y_dense = evaluate(sol, jnp.asarray(t_dense))
    assert orthogonality_error(y_dense[0]) <= ORTHO_TOL
    y_ref, _ = reference(args, t_dense)
    e_dense = error(y_dense, y_ref)
    e_t1 = error(final(sol), reference_ts_t1("coupled")[1])
    print(f"dense error {e_dense:.2e}, error at t1 {e_t1:.2e}")
    assert e_dense < 2 * e_t1 + 1e-10 and e_dense < 15 * 1e-8
    # At the step times the dense output reproduces the steps; at TS it is SaveAt(ts).
    y_at_steps = evaluate(sol, jnp.asarray(t_steps))
    y_at_ts = evaluate(sol, jnp.asarray(TS))
    for a, b in [(y_at_steps, y_steps), (y_at_ts, sol.ys[2])]:
        for leaf_a, leaf_b in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
            np.testing.assert_allclose(leaf_a, leaf_b, rtol=0, atol=1e-13)


@eqx.filter_jit
def _solve_event(y0, args, progress_meter):
    event = diffrax.Event(
        lambda t, y, args, **kwargs: y[1][3], root_finder=optx.Newton(rtol=1e-12, atol=1e-12)
    )
    return diffrax.diffeqsolve(
        TERM,
        RKMK54(),
        0.0,
        T1,
        None,
        y0,
        args,
        event=event,
        stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-10),
        progress_meter=progress_meter,
        max_steps=MAX_STEPS,
    )


def test_event_and_progress_meter(capsys):
    """Stop when v_x crosses zero (root found on the group-valued dense output)."""
    args = PROBLEMS["coupled"]
    sol = _solve_event(_f64(Y0), _f64(args), diffrax.TextProgressMeter())
    assert "0.00%" in capsys.readouterr().out
    assert bool(sol.event_mask)
    t_event = float(sol.ts[0])
    y_event = jax.tree.map(lambda a: np.asarray(a[0]), sol.ys)
    assert orthogonality_error(y_event[0]) <= ORTHO_TOL
    assert abs(y_event[1][3]) < 1e-9

    def vx(t, z):
        return z[19]

    vx.terminal = True
    _, res = reference(args, [], event=vx)
    t_ref = res.t_events[0][0]
    z_ref = res.y_events[0][0]
    y_ref = (z_ref[:16].reshape(4, 4), z_ref[16:])
    print(f"event at {t_event}, reference {t_ref}")
    assert 0.2 < t_event < 1.0
    assert abs(t_event - t_ref) < 1e-8
    assert error(y_event, y_ref) < 1e-8


# --------------------------------------------------------------------------- autodiff

_W = np.random.default_rng(2)
W_G = _W.normal(size=(4, 4))
W_X = _W.normal(size=6)
THETA0 = np.concatenate([np.zeros(6), X0, PROBLEMS["coupled"]])
GRAD_STEPS = 100  # RecursiveCheckpointAdjoint at fixed steps: FD sees the same discrete map
BACKSOLVE_RTOL = 1e-12


def _unpack(theta):
    """θ = (η, x0, args) with g0 = G0 exp(η): the gradient in η is the tangent one."""
    return (jnp.asarray(G0) @ lie.se3_exp(theta[:6]), theta[6:12]), theta[12:]


def _loss_of(y1):
    g1, x1 = y1
    return jnp.sum(W_G * g1) + jnp.dot(W_X, x1)


@eqx.filter_jit
@eqx.filter_grad
def _grad(theta, adjoint, controller, dt0):
    y0, args = _unpack(theta)
    sol = diffrax.diffeqsolve(
        TERM,
        RKMK54(),
        0.0,
        T1,
        dt0,
        y0,
        args,
        stepsize_controller=controller,
        adjoint=adjoint,
        max_steps=MAX_STEPS,
    )
    return _loss_of(jax.tree.map(lambda a: a[0], sol.ys))


_unpack_jit = jax.jit(_unpack)

_GRADS = {}


def recursive_checkpoint_grad():
    if "rc" not in _GRADS:
        _GRADS["rc"] = np.asarray(
            _grad(
                _f64(THETA0),
                diffrax.RecursiveCheckpointAdjoint(),
                diffrax.ConstantStepSize(),
                _f64(T1 / GRAD_STEPS),
            )
        )
    return _GRADS["rc"]


def test_grad_vs_finite_differences():
    """jax.grad through diffeqsolve (RecursiveCheckpointAdjoint) in the group tangent η,
    the initial x and the parameters, against central differences of the same solves."""
    grad = recursive_checkpoint_grad()

    def loss(theta):
        y0, args = _unpack_jit(_f64(theta))
        controller = diffrax.ConstantStepSize()
        return float(_loss_of(final(solve(RKMK54(), controller, args, y0=y0, dt0=T1 / GRAD_STEPS))))

    eps = 1e-5
    fd = np.array(
        [(loss(THETA0 + eps * e) - loss(THETA0 - eps * e)) / (2 * eps) for e in np.eye(len(THETA0))]
    )
    print("grad", grad, "\nfd  ", fd)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-7 * np.abs(grad).max())


def test_backsolve_adjoint():
    """BacksolveAdjoint integrates the augmented state (y, a_y, a_args, a_terms) backwards
    with RKMK54 itself (its first leaf is still the pose, every other leaf is Euclidean),
    adaptively; the continuous adjoint agrees with the discrete gradient to tolerance."""
    controller = diffrax.PIDController(rtol=BACKSOLVE_RTOL, atol=BACKSOLVE_RTOL)
    grad_bs = np.asarray(_grad(_f64(THETA0), diffrax.BacksolveAdjoint(), controller, None))
    grad_rc = recursive_checkpoint_grad()
    print("backsolve", grad_bs, "\nrecursive", grad_rc)
    np.testing.assert_allclose(grad_bs, grad_rc, rtol=1e-5, atol=1e-7 * np.abs(grad_rc).max())


# --------------------------------------------------------------------------- transformations


@eqx.filter_jit
def _solve_batch(y0s, args):
    def one(y0):
        sol = diffrax.diffeqsolve(
            TERM,
            RKMK54(),
            0.0,
            T1,
            None,
            y0,
            args,
            stepsize_controller=diffrax.PIDController(rtol=1e-8, atol=1e-8),
            max_steps=MAX_STEPS,
        )
        return jax.tree.map(lambda a: a[0], sol.ys)

    return jax.vmap(one)(y0s)


def test_vmap_matches_loop():
    args = PROBLEMS["coupled"]
    rng = np.random.default_rng(3)
    etas = 0.5 * rng.normal(size=(3, 6))
    g0s = np.stack(
        [np.asarray(_unpack_jit(_f64(np.concatenate([e, X0, args])))[0][0]) for e in etas]
    )
    x0s = X0 + 0.3 * rng.normal(size=(3, 6))
    g_b, x_b = _solve_batch(_f64((g0s, x0s)), _f64(args))
    for i in range(3):
        g_i, x_i = final(solve(RKMK54(), pid(1e-8), args, y0=(g0s[i], x0s[i])))
        np.testing.assert_allclose(g_b[i], g_i, rtol=0, atol=1e-12)
        np.testing.assert_allclose(x_b[i], x_i, rtol=0, atol=1e-12)
    assert orthogonality_error(g_b) <= ORTHO_TOL


def test_max_steps_result():
    sol = solve(LieEuler(), diffrax.ConstantStepSize(), PROBLEMS["rigid"], dt0=T1 / (MAX_STEPS + 5))
    assert sol.result == diffrax.RESULTS.max_steps_reached


def test_no_recompilation():
    solve(RKMK54(), pid(1e-6), PROBLEMS["rigid"])
    count = TRACES["solve"]
    y0 = (G0, X0 + 0.1)
    sol = solve(
        RKMK54(), pid(1e-7), PROBLEMS["coupled"], y0=y0, t1=1.5, ts=np.linspace(0.1, 1.4, 7)
    )
    assert sol.result == diffrax.RESULTS.successful
    solve(RKMK54(), pid(1e-9), PROBLEMS["rigid"])
    assert TRACES["solve"] == count


def test_reverse_time():
    args = PROBLEMS["coupled"]
    y1 = final(solve(RKMK54(), pid(1e-12), args))
    sol = solve(RKMK54(), pid(1e-12), args, y0=y1, t0=T1, t1=0.0)
    assert sol.result == diffrax.RESULTS.successful
    y0 = final(sol)
    assert orthogonality_error(at_steps(sol)[1][0]) <= ORTHO_TOL
    assert error(y0, Y0) < 1e-10


class BodyTerm(AbstractBodyTerm):
    """`TERM` with its twist given directly, as `SceneTerm` gives it. Its `vf` (which
    diffrax evaluates for shapes only) is NaN, so a solve that read the twist off
    $\\dot g$ instead would fail."""

    def body_vf(self, t, y, args):
        return body_vector_field(t, y, args)

    def vf(self, t, y, args):
        return jax.tree.map(lambda a: jnp.full_like(a, jnp.nan), vector_field(t, y, args))

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def prod(self, vf, control):
        return jax.tree.map(lambda v: control * v, vf)


@eqx.filter_jit
def _fixed_steps(term, y0, args, t0, t1):
    return diffrax.diffeqsolve(
        term, RKMK54(), t0, t1, (t1 - t0) / 16, y0, args, saveat=diffrax.SaveAt(steps=True)
    ).ys


def test_body_term():
    """A term that gives its twist (`AbstractBodyTerm`) is read directly, inside the wrapper
    `diffeqsolve` puts around terms too, forwards and backwards in time (the coupled
    problem depends on t): the same steps as reading $(g^{-1}\\dot g)^\\vee$ off `TERM`."""
    args = _f64(PROBLEMS["coupled"])
    for t0, t1 in ((0.0, T1), (T1, 0.0)):
        ends = _f64((t0, t1))
        embedded = _fixed_steps(TERM, _f64(Y0), args, *ends)
        body = _fixed_steps(BodyTerm(), _f64(Y0), args, *ends)
        for a, b in zip(jax.tree.leaves(embedded), jax.tree.leaves(body), strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)


# --------------------------------------------------------------------------- one step


@jax.jit
def _one_step(solver_state, made_jump):
    solver, args = RKMK54(), jnp.asarray(PROBLEMS["coupled"])
    t0, t1 = 0.0, 0.3
    y1, y_error, dense_info, _, result = solver.step(
        TERM, t0, t1, _f64(Y0), args, solver_state, made_jump
    )
    interp = RKMK54.interpolation_cls(t0=jnp.asarray(t0), t1=jnp.asarray(t1), **dense_info)
    values = [interp.evaluate(t) for t in (t0, 0.1, 0.2, t1)]
    return y1, y_error, values, interp.evaluate(0.1, 0.2), result


def test_step_internals():
    args = jnp.asarray(PROBLEMS["coupled"])
    solver = RKMK54()
    with pytest.raises(ValueError, match="first leaf"):
        solver.init(TERM, 0.0, 1.0, (X0, G0), args)

    # Every stage is evaluated each step: no stored stage, so a jump changes nothing.
    assert solver.init(TERM, 0.0, 0.3, _f64(Y0), args) is None
    y1, y_error, values, increment, result = _one_step(None, jnp.array(False))
    assert result == diffrax.RESULTS.successful
    y1_jump = _one_step(None, jnp.array(True))[0]
    for a, b in zip(jax.tree.leaves(y1), jax.tree.leaves(y1_jump), strict=True):
        np.testing.assert_array_equal(a, b)

    # The error estimate is a Lie-algebra increment arranged as a 4x4: (Ω - Ω̂)^.
    E = np.asarray(y_error[0])
    np.testing.assert_array_equal(E[3], 0.0)
    np.testing.assert_array_equal(np.diag(E), 0.0)
    np.testing.assert_array_equal(E[:3, :3], -E[:3, :3].T)
    y_ref, _ = reference(np.asarray(args), [0.3])
    true_error = error(y1, jax.tree.map(lambda a: a[0], y_ref))
    estimate = max(np.abs(E).max(), np.abs(np.asarray(y_error[1])).max())
    print(f"one step: true error {true_error:.2e}, estimate {estimate:.2e}")
    assert true_error < estimate < 1e-3

    # Dense output: exact at t0, the step at t1, increments are differences.
    for a, b in zip(jax.tree.leaves(values[0]), jax.tree.leaves(Y0), strict=True):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(jax.tree.leaves(values[-1]), jax.tree.leaves(y1), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)
    for inc, a, b in zip(
        *(jax.tree.leaves(v) for v in (increment, values[1], values[2])), strict=True
    ):
        np.testing.assert_allclose(inc, b - a, rtol=0, atol=1e-15)
