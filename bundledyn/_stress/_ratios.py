"""Cases at extreme ratios: a thin rod, a heavy link, a stiff spring, a folded chain, a nearly
flat affine body, a ball joint turning many times."""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from .. import lie
from .._effects import ShapeSpring
from .._scene import Scene
from .._simulate import simulate
from .._state import State
from .._systems._affine_body import AffineBody, stretch
from .._systems._rigid_body import RigidBody
from ._conservation import energy_row, free_run, momentum_row
from ._models import chain
from ._row import StressRow
from ._start import XI0


def _free_rows(case, system, q, qdot, *, t1, rtol, effects=(), xi=XI0):
    """Energy and momentum rows of `system` moving from `(q, xi, qdot)` under `effects`."""
    state = State(jnp.eye(4), jnp.asarray(q, dtype=float), jnp.asarray(xi, dtype=float),
                  jnp.asarray(qdot, dtype=float))  # fmt: skip
    return free_run(case, Scene(system, list(effects)), state, t1=t1, rtol=rtol)[1:]


def thin_rod(*, t1: float = 10.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    r"""A rod whose axial moment is $10^{-8}$ of its transverse ones, tumbling.

    Guards against codes that must bound or rebalance such inertias to stay stable (MuJoCo's
    compiler offers `boundinertia` and `balanceinertia` for them) and against momentum lost
    to cancellation in Euler's equations, where $\dot\omega_1$ divides by $I_1$.

    **Returns:**

    Rows: energy and spatial momentum over `t1` at `rtol`.
    """
    body = RigidBody(1.0, jnp.zeros(3), jnp.diag(jnp.array([1e-8, 1.0, 1.0 + 5e-9])))
    return _free_rows("thin_rod (moments 1e-8 : 1)", body, (), (), t1=t1, rtol=rtol,
                      xi=(1.0, 0.3, 0.2, 0.1, 0.0, 0.0))  # fmt: skip


def mass_ratio(*, t1: float = 5.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    """A three-link chain of masses 1e3, 1e-3 and 1 kg: 10⁶ between neighbours.

    Guards against the light link's motion lost to cancellation: its inertia is a part in
    10⁶ of the locked inertia the base's equation inverts.

    **Returns:**

    Rows: energy and spatial momentum.
    """
    return _free_rows("mass_ratio (1e6 between links)", chain((1e3, 1e-3, 1.0)),
                      (0.3, -0.5), (1.0, -2.0), t1=t1, rtol=rtol)  # fmt: skip


def stiff_springs(*, t1: float = 2.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    """A chain whose two joint springs differ 10⁶ in stiffness: periods 10³ apart.

    Explicit `RKMK87` (the default) resolves the stiff joint's oscillation, as it must when
    that joint moves (its energy is part of the answer); its step count scales with the
    stiff period. Which solver to use is measured, not assumed: with the stiff joint at
    rest, where an implicit method should gain most, diffrax's L-stable `Kvaerno5` (on
    the pose's embedding, at the same tolerance) takes more steps than `RKMK87` — the
    explicit default stays the right choice, and the case fails if that ever changes.
    Guards against methods that stay stable by damping the stiff mode away (energy lost).

    **Returns:**

    Rows: energy (the springs' included) and spatial momentum, the note giving the steps;
    `RKMK87`'s steps over `Kvaerno5`'s with the stiff joint at rest (bound 1).
    """
    system = chain((1.0, 1.0, 1.0))
    spring = ShapeSpring(jnp.array([1e-2, 1e4]))
    case = "stiff_springs (stiffness 1e-2 : 1e4)"
    rows = _free_rows(case, system, (0.3, 1e-3), (0.5, 0.0), t1=t1, rtol=rtol, effects=(spring,))
    at_rest = State(jnp.eye(4), jnp.array([0.3, 0.0]), jnp.asarray(XI0), jnp.array([0.5, 0.0]))
    steps = [
        int(simulate(Scene(system, [spring]), at_rest, jnp.asarray(t1), solver=solver,
                     rtol=1e-8, atol=1e-8).stats["num_steps"])
        for solver in (None, diffrax.Kvaerno5())
    ]  # fmt: skip
    return (
        *rows,
        StressRow(case, f"steps, RKMK87 over implicit Kvaerno5, stiff joint at rest ({t1:g} s, 1e-8)",
                  steps[0] / steps[1], 1.0, f"{steps[0]} and {steps[1]} steps"),
    )  # fmt: skip


def folded_chain(*, t1: float = 5.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    """A three-link chain folded back on itself (joints at ±π, the links on one another).

    Guards against models whose metric or joint charts degenerate at a full fold.

    **Returns:**

    Rows: energy and spatial momentum.
    """
    return _free_rows("folded_chain (joints at ±π)", chain((1.0, 1.5, 2.0)), (np.pi, -np.pi),
                      (0.5, -0.3), t1=t1, rtol=rtol)  # fmt: skip


def _deformation_gradient(g, q):
    r"""$F = R\,U(q)$: the affine body's deformation gradient in the frame of the scene."""
    return g[:3, :3] @ stretch(q)


def degenerate_stretch(*, t1: float = 1.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    r"""An affine body squashed to singular values (1, 1, 10⁻⁶), turning and stretching.

    With no force each material point moves on a straight line, so the deformation gradient
    is $F(t) = F_0 + t\dot F_0$ exactly: the case compares $F(t_1) = R\,U(q)$ with it
    (relative to $|F|$), besides energy and momentum. The thin axis grows here; a velocity
    that flattens the body through $\det F = 0$ leaves the stretch chart ($U$ positive
    definite), and the solve stops at `max_steps` there.

    Guards against deformable-body codes that invert the deformation gradient (nearly
    singular here) or lose its small singular value to rounding.

    **Returns:**

    Rows: $F(t_1)$ against the closed form, energy, spatial momentum.
    """
    body = AffineBody(3.0, 3.0 / 5.0 * jnp.diag(jnp.array([0.25, 0.09, 0.04])))
    q = jnp.array([0.0, 0.0, np.log(1e-6), 0.1, 0.0, 0.0])
    qdot = jnp.array([0.2, -0.1, 0.5, 0.1, 0.0, 0.0])  # no shear of the thin axis
    xi = jnp.array(XI0)
    state = State(jnp.eye(4), q, xi, qdot)
    traj = simulate(Scene(body), state, t1, rtol=rtol, atol=rtol)
    F0, Fdot0 = jax.jvp(
        lambda s: _deformation_gradient(jnp.eye(4) @ lie.se3_exp(s * xi), q + s * qdot),
        (0.0,), (1.0,),
    )  # fmt: skip
    F1 = _deformation_gradient(traj.g[-1], traj.q[-1])
    error = float(jnp.max(jnp.abs(F1 - F0 - t1 * Fdot0)) / jnp.max(jnp.abs(F0 + t1 * Fdot0)))
    case = "degenerate_stretch (singular values 1e-6)"
    return (
        StressRow(
            case, "deformation gradient vs straight-line motion F0 + t F'0", error, 1e2 * rtol
        ),  # fmt: skip
        energy_row(case, traj, 1e2 * rtol),
        momentum_row(case, traj, 1e2 * rtol),
    )


def ball_turns(*, turns: float = 20.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    r"""A wheel on a ball joint spinning `turns` times about a nearly fixed axis.

    The rotation vector's chart degenerates at $|\varphi| = 2\pi$; the solvers rechart it
    (`SceneTerm.recharted`). Guards against the grind to `max_steps` that the chart's
    singularity caused before, where MuJoCo (quaternions) had no trouble.

    **Returns:**

    Rows: energy and spatial momentum; the note gives the steps.
    """
    system = chain((5.0, 1.0), ball=True)
    spin = 2 * np.pi
    return _free_rows(f"ball_turns ({turns:g} turns)", system, (0.0, 0.0, 0.0),
                      (spin, 1e-5 * spin, 0.0), t1=turns, rtol=rtol, xi=(0.0,) * 6)  # fmt: skip
