"""The peer: `sympy.physics.mechanics.KanesMethod`'s equations made numeric and integrated as a
sympy user does, with `lambdify` and scipy's `DOP853`."""

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class KaneModel:
    """A derived `KanesMethod` and the numbers of its parameters.

    `velocity_constraints` are the expressions (linear in the speeds) that vanish; the
    dependent speeds are the method's last `len(velocity_constraints)`."""

    method: object
    velocity_constraints: list
    values: dict


def derive_equations(model):
    """Forces sympy to form the full mass matrix and forcing (properties it builds lazily)."""
    return model.method.mass_matrix_full, model.method.forcing_full


def numeric_field(model):
    """$\\dot x = f(t, x)$ for $x = (q, u)$ in the method's order: `mass_matrix_full` and
    `forcing_full` lambdified (common subexpressions eliminated) and solved with numpy."""
    import sympy as sm

    method = model.method
    params = list(model.values)
    mass, forcing = derive_equations(model)
    both = sm.lambdify([list(method.q), list(method.u), params], [mass, forcing], cse=True)
    values = [model.values[p] for p in params]
    n = len(method.q)

    def field(t, x):
        M, F = both(x[:n], x[n:], values)
        return np.linalg.solve(np.asarray(M, dtype=float), np.asarray(F, dtype=float).ravel())

    return field


def dependent_speeds(model):
    """`speeds(q, u_independent) -> u` (all speeds, in the method's order): the velocity
    constraints, linear in the speeds, solved for the dependent ones."""
    import sympy as sm

    method = model.method
    constraints = sm.Matrix(model.velocity_constraints)
    m = len(model.velocity_constraints)
    u = list(method.u)
    independent, dependent = u[: len(u) - m], u[len(u) - m :]
    params = list(model.values)
    values = [model.values[p] for p in params]
    args = [list(method.q), independent, params]
    matrix = sm.lambdify(args, constraints.jacobian(dependent), cse=True)
    rest = sm.lambdify(args, constraints.subs({d: 0 for d in dependent}), cse=True)

    def speeds(q, u_independent):
        A = np.asarray(matrix(q, u_independent, values), dtype=float)
        b = np.asarray(rest(q, u_independent, values), dtype=float).ravel()
        return np.concatenate([u_independent, np.linalg.solve(A, -b)])

    return speeds


def integrate(field, x0, ts, rtol):
    """The states at `ts` from `x0`, by scipy's `DOP853` at `rtol = atol`."""
    from scipy.integrate import solve_ivp

    done = solve_ivp(field, (ts[0], ts[-1]), x0, method="DOP853", t_eval=ts, rtol=rtol, atol=rtol)
    if not done.success:
        raise RuntimeError(f"DOP853 failed: {done.message}")
    return done.y.T
