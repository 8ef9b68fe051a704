"""Scene modes: every mode meets the same battery, and a mode defined here alone runs
through `simulate`, gradients and the command line.

The battery, for every scene of `MODE_SCENES` (each built-in mode, a moving frame, and
`HingedBody`): the layout's round trips, the field against the reference form (the rows of
it that the mode integrates), energy where it is conserved, and `StoredStepsAdjoint`'s
gradient against `RecursiveCheckpointAdjoint`'s.

`HingedBody` is a rigid body turning about an axis fixed in space and in the body, through
its section frame's origin: a physical pendulum under gravity. Nothing outside this file
knows it; the library reaches it only through `AbstractMode`.
"""

import dataclasses
import functools as ft

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import registry
from registry import ADJOINTS, SOLVERS, ModeScene

import bundledyn as bd
from bundledyn._cli import main
from bundledyn._dynamics import reference_accelerations

MASS, ARM, G = 2.0, 0.3, 9.81
INERTIA_CM = jnp.diag(jnp.array([0.05, 0.04, 0.03]))
AXIS = jnp.array([1.0, 0.0, 0.0])


class HingedBody(bd.AbstractMode):
    r"""A rigid body on a hinge through its section frame's origin: $x = (\omega)$, the
    rate about the unit `axis`, $\xi = (\omega a, 0)$, and $a^T I a\,\dot\omega = a\cdot\tau$
    (the axial part of Euler's equation; the hinge's reactions have no torque about it)."""

    axis: jax.Array

    @property
    def shape(self):
        return bd.Free()

    @property
    def base(self):
        return bd.FloatingBase()

    def check(self, system, frame):
        if system.shape_dim != 0 or frame is not None:
            raise ValueError("`HingedBody` is for a rigid body in the Galilean frame.")

    def pack(self, scene, t, g, q, U, qdot):
        return g, (self.axis @ U[:3])[None]

    def unpack(self, scene, t, y):
        g, x = y
        U = jnp.concatenate([x[0] * self.axis, jnp.zeros(3, x.dtype)])
        return g, x[:0], U, x[:0]

    def encode(self, scene, t, state):
        return self.pack(scene, t, state.g, state.q, state.xi, state.qdot)

    def decode(self, scene, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return bd.State(g, q, U, qdot), U

    def body_field(self, scene, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        torque = scene.forces(bd.Kinematics(t, g, q, U, qdot))[0][:3]
        inertia = self.axis @ bd.locked_inertia(scene.system, q)[:3, :3] @ self.axis
        return U, (self.axis @ torque / inertia)[None]

    def kinematics(self, scene, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return bd.Kinematics(t, g, q, U, qdot)

    def recharted(self, scene, t, y):
        return y

    def constraint_residual(self, scene, state):
        return state.xi[:0]  # the hinge is kept by the layout itself

    def window_chart(self, scene):
        raise ValueError("`HingedBody` scenes are not identified (no window chart).")


BODY = bd.RigidBody(MASS, jnp.array([0.0, 0.0, -ARM]), INERTIA_CM)
SCENE = bd.Scene(BODY, (bd.Gravity(G),), mode=HingedBody(AXIS))
T1 = 2.0


def _start(theta, omega):
    g = bd.lie.se3_exp(jnp.concatenate([theta * AXIS, jnp.zeros(3)]))
    return bd.State(g, xi=jnp.concatenate([omega * AXIS, jnp.zeros(3)]))


def _angle(g):
    return jnp.arctan2(g[..., 2, 1], g[..., 1, 1])


def _pendulum(theta0, omega0, ts):
    r"""$\ddot\theta = -(m g l / I_a)\sin\theta$, the compound pendulum, integrated on its own."""
    inertia = INERTIA_CM[0, 0] + MASS * ARM**2
    field = lambda t, y, args: jnp.stack([y[1], -MASS * G * ARM / inertia * jnp.sin(y[0])])
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(field),
        diffrax.Tsit5(),
        0.0,
        ts[-1],
        None,
        jnp.stack([theta0, omega0]),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=1e-13, atol=1e-13),
        max_steps=None,
    )
    return sol.ys


@eqx.filter_jit
def _simulate(theta0, omega0, ts):
    return bd.simulate(
        SCENE, _start(theta0, omega0), ts[-1], rtol=1e-12, atol=1e-12, saveat=diffrax.SaveAt(ts=ts)
    )


def test_a_mode_of_the_test_file_simulates_the_compound_pendulum():
    ts = jnp.linspace(0.0, T1, 21)
    theta0, omega0 = jnp.asarray(1.2), jnp.asarray(0.5)
    traj = _simulate(theta0, omega0, ts)
    expected = _pendulum(theta0, omega0, ts)
    np.testing.assert_allclose(_angle(traj.g), expected[:, 0], atol=1e-9)
    np.testing.assert_allclose(traj.xi[:, 0], expected[:, 1], atol=1e-9)
    energy = traj.diagnostics().energy  # T + the gravity's potential, by the library's own code
    np.testing.assert_allclose(energy, energy[0], atol=1e-10 * abs(float(energy[0])))


def test_gradients_through_a_mode_of_the_test_file():
    def final_rate(omega0, mass):
        scene = eqx.tree_at(lambda s: s.system.mass, SCENE, mass)
        state = _start(jnp.asarray(0.7), omega0)
        traj = bd.simulate(scene, state, T1, rtol=1e-12, atol=1e-12)
        return traj.xi[-1, 0]

    args = (jnp.asarray(0.3), jnp.asarray(MASS))
    # Compiled whole, once: the gradient's program gives the four differences' values too
    # (a program of the value alone would compile the solve again).
    value_and_grad = jax.jit(jax.value_and_grad(final_rate, argnums=(0, 1)))
    grads = value_and_grad(*args)[1]
    for k, grad in enumerate(grads):
        step = 1e-5
        up = list(args)
        down = list(args)
        up[k], down[k] = args[k] + step, args[k] - step
        central = (float(value_and_grad(*up)[0]) - float(value_and_grad(*down)[0])) / (2 * step)
        np.testing.assert_allclose(grad, central, rtol=1e-6, atol=1e-8)
    # The mass cancels in a compound pendulum whose inertia is all the point mass's; here it
    # does not (I_cm ≠ 0), so the mass's gradient is not zero and the check above means something.
    assert abs(float(grads[1])) > 1e-4


def test_the_command_line_runs_a_mode_of_the_test_file(tmp_path, monkeypatch, capsys):
    cat = bd.SceneFile.load(bd.scenes / "falling_cat.toml")
    hinged = dataclasses.replace(
        cat, scene=SCENE, state=_start(jnp.asarray(1.2), jnp.asarray(0.5)), solids=None
    )
    monkeypatch.setattr(bd.SceneFile, "load", classmethod(lambda cls, path: hinged))
    assert main(["run", "hinged.toml", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "mode HingedBody" in printed
    with np.load(tmp_path / "falling_cat.npz") as archive:
        saved = dict(archive)
    expected = _pendulum(jnp.asarray(1.2), jnp.asarray(0.5), jnp.asarray(saved["ts"]))
    np.testing.assert_allclose(_angle(saved["g"]), expected[:, 0], atol=1e-7)
    np.testing.assert_allclose(saved["energy"], saved["energy"][0], rtol=1e-7)
    assert (tmp_path / "falling_cat_drift.png").stat().st_size > 0


def test_a_mode_and_a_shape_or_base_together_are_refused():
    with pytest.raises(ValueError, match="either `mode` or `shape` and `base`"):
        bd.Scene(BODY, mode=HingedBody(AXIS), base=bd.PrescribedBase.fixed())
    with pytest.raises(ValueError, match="rigid body in the Galilean frame"):
        bd.Scene(BODY, mode=HingedBody(AXIS), frame=bd.Boosted(jnp.ones(3)))


# Every mode's scene of the registry, and the hinged body, whose mode this file alone knows.
MODE_SCENES = {
    **registry.MODE_SCENES,
    "hinged_body": ModeScene(SCENE, _start(jnp.asarray(1.2), jnp.asarray(0.5)), slice(0, 1), True),
}
MODE_NAMES = list(MODE_SCENES)


def test_every_built_in_mode_is_in_the_battery():
    built_in = {
        bd.FreeShapeMode, bd.RigidBodyMode, bd.PrescribedShapeMode, bd.PrescribedBaseMode,
        bd.CentreOfMassMode,
    }  # fmt: skip
    assert built_in <= {type(scene.mode) for scene, *_ in MODE_SCENES.values()}


@eqx.filter_jit  # one program per mode, not one per primitive
def _round_trips(scene, state, t):
    """The encoded state and, from it, what the layout's round trips give back: encoded
    again after decoding, packed again after unpacking, and the locked velocity and the
    decoded velocity both ways."""
    term = bd.SceneTerm(scene)
    y = term.encode(t, state)
    decoded = term.decode(t, y)
    state_again, U = term.decode_with_locked_velocity(t, y)
    unpacked = term.unpack(t, y)
    return (
        y,
        term.encode(t, decoded),
        term.pack(t, *unpacked),
        (U, unpacked[2]),
        (state_again.xi, decoded.xi),
    )


@pytest.mark.parametrize("name", MODE_NAMES)
def test_layout_round_trips(name):
    scene, state, _, _ = MODE_SCENES[name]
    y, again, repacked, locked, decoded = _round_trips(scene, state, jnp.asarray(0.37))
    for a, b in zip(jax.tree.leaves(again), jax.tree.leaves(y), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14)
    for a, b in zip(jax.tree.leaves(repacked), jax.tree.leaves(y), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(*locked, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(*decoded, rtol=1e-14, atol=1e-14)


@eqx.filter_jit  # one program per mode, not one per primitive
def _reference_residual(scene, t, state):
    r"""$G a - h$ of the reference form in the Galilean frame, with $a$ the rates of the
    decoded velocities along the mode's field (by a JVP of `kinematics` along it)."""
    term = bd.SceneTerm(scene)
    y = term.encode(t, state)
    xi_pose, xdot = term.body_vf(t, y, None)
    tangent = (y[0] @ bd.lie.hat(xi_pose), xdot)

    def velocities(t, y):
        kin = term.kinematics(t, y)
        return kin.xi, kin.qdot

    kin = term.kinematics(t, y)
    _, (xi_dot, qddot) = jax.jvp(velocities, (t, y), (jnp.ones_like(t), tangent))
    F, Q = scene.forces(kin)
    system = scene.system
    G = system.metric(kin.q)
    a = jnp.concatenate([xi_dot, qddot])
    a_ref = jnp.concatenate(reference_accelerations(system, kin.q, kin.xi, kin.qdot, F, Q))
    # G a_ref = h: the rows the mode integrates hold where G (a - a_ref) vanishes on them.
    return G @ (a - a_ref), jnp.max(jnp.abs(G @ a_ref))


@pytest.mark.parametrize("name", MODE_NAMES)
def test_field_against_the_reference_form(name):
    scene, state, rows, _ = MODE_SCENES[name]
    residual, size = (np.asarray(x) for x in _reference_residual(scene, jnp.asarray(0.37), state))
    if isinstance(scene.mode, HingedBody):
        residual = (np.asarray(AXIS) @ residual[:3])[
            None
        ]  # the axial row: the hinge reacts in the others
    assert float(np.max(np.abs(residual[rows]))) < 1e-12 * max(float(size), 1.0)


@pytest.mark.parametrize("name", [n for n in MODE_NAMES if MODE_SCENES[n][3]])
def test_energy_is_conserved(name):
    scene, state, _, _ = MODE_SCENES[name]
    traj = bd.simulate(
        scene, state, 1.0, rtol=1e-11, atol=1e-11, saveat=diffrax.SaveAt(ts=jnp.linspace(0, 1, 5))
    )
    energy = traj.diagnostics().energy
    kinetic = jax.vmap(ft.partial(bd.kinetic_energy, scene.system))(traj.q, traj.xi, traj.qdot)
    # The total is a difference of kinetic and potential energies: tolerance on their size.
    scale = float(np.max(np.abs(energy)) + np.max(np.abs(kinetic)))
    np.testing.assert_allclose(energy, energy[0], rtol=0, atol=1e-9 * scale)


# Two gradients compiled per mode: the rigid body and the hinged body everyday, the rest
# (whose free-shape field test_adjoint.py checks everyday) in the slow part.
_EVERYDAY_ADJOINT = ("rigid_body", "hinged_body")


@pytest.mark.parametrize(
    "name",
    [n if n in _EVERYDAY_ADJOINT else pytest.param(n, marks=pytest.mark.slow) for n in MODE_NAMES],
)
def test_stored_steps_adjoint_against_recursive_checkpoints(name):
    scene, state, _, _ = MODE_SCENES[name]

    def loss(velocities, adjoint):
        start = dataclasses.replace(state, xi=velocities[0], qdot=velocities[1])
        # RKMK4's four stages compile in a third of RKMK87's time; the adjoint replays both.
        traj = bd.simulate(scene, start, 0.4, solver=SOLVERS["RKMK4"], dt0=0.05, adjoint=adjoint)
        return jnp.sum(traj.xi[-1] ** 2) + jnp.sum(traj.g[-1, :3, 3]) + jnp.sum(traj.qdot[-1])

    velocities = (state.xi, state.qdot)
    gradient = eqx.filter_jit(jax.grad(loss))  # one program each, not a jvp's and a transpose's
    stored = gradient(velocities, ADJOINTS["stored steps"])
    checkpointed = gradient(velocities, ADJOINTS["checkpointed"])
    for a, b in zip(stored, checkpointed, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10)
    # The velocities the mode integrates reach the loss (a given base's do not).
    assert max(float(jnp.max(jnp.abs(g), initial=0.0)) for g in stored) > 1e-3
