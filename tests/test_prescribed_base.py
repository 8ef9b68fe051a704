"""A prescribed base: the shape equation driven by a given motion of the section frame.

Checked against the reference (Hamel / Euler–Poincaré) form with the base's acceleration
given, against MuJoCo (an arm whose root MuJoCo welds to the world), and by the energy of
an arm on a fixed base.
"""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import SYSTEMS, random_shapes

import bundledyn as bd

mujoco = pytest.importorskip("mujoco")

ARM = """
<mujoco model="arm">
  <option gravity="0 0 -9.81" integrator="RK4" timestep="1e-4"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="base" pos="0.1 -0.2 1.0" quat="0.95 0.1 0.2 -0.2">
      <inertial pos="0 0 0" mass="5" diaginertia="0.1 0.1 0.1"/>
      <body name="upper" pos="0 0 -0.05">
        <joint name="shoulder" type="hinge" axis="0 1 0.2"/>
        <inertial pos="0.02 0.01 -0.2" mass="1.3" fullinertia="0.02 0.021 0.004 0.001 -0.002 0.0005"/>
        <body name="fore" pos="0.01 0 -0.4">
          <joint name="elbow" type="hinge" axis="1 0.1 0" pos="0 0.01 0.02"/>
          <inertial pos="0 0.02 -0.15" mass="0.9" fullinertia="0.01 0.011 0.002 -0.0005 0.001 0.0004"/>
          <body name="hand" pos="0 0 -0.3">
            <joint name="wrist" type="ball" pos="0 0 0.01"/>
            <inertial pos="0.01 0 -0.05" mass="0.3" diaginertia="0.001 0.0012 0.0008"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("name", ["chain5", "tree4", "affine_body", "mjcf_chain5"])
def test_driven_shape_equation_is_the_reference_forms_shape_rows(name, key):
    """With (ξ, ξ̇, q̈) given, the wrench and shape force of the reference form give back q̈
    through `driven_shape_acceleration`, and `driven_shape_force` is its inverse."""
    system = SYSTEMS[name]()
    d = system.shape_dim
    keys = jax.random.split(key, 5)
    q = random_shapes(system, keys[0], 1)[0]
    xi, xi_dot = jax.random.normal(keys[1], (2, 6))
    qdot, qddot = jax.random.normal(keys[2], (2, d))

    @jax.jit  # one program, not one per primitive
    def driven(q, xi, xi_dot, qdot, qddot):
        G, dG = system.metric_and_derivative(q)
        v = jnp.concatenate([xi, qdot])
        p = G[:6] @ v
        bias = (
            jnp.concatenate([bd.lie.ad(xi).T @ p, 0.5 * (dG @ v) @ v])
            - jnp.tensordot(qdot, dG, 1) @ v
        )
        forces = G @ jnp.concatenate([xi_dot, qddot]) - bias  # (F_b, Q_H) of that motion
        Q = forces[6:]
        return (
            Q,
            bd.driven_shape_acceleration(system, q, xi, xi_dot, qdot, Q),
            bd.driven_shape_force(system, q, xi, xi_dot, qdot, qddot),
        )

    Q, acceleration, force = driven(q, xi, xi_dot, qdot, qddot)
    np.testing.assert_allclose(acceleration, qddot, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(force, Q, rtol=1e-10, atol=1e-10)


def test_an_arm_on_a_fixed_base_moves_as_mujoco_moves_it():
    """MuJoCo welds a root without a free joint to the world; bundledyn imports the same
    tree and holds its base with `PrescribedBase.fixed`: 1 s under gravity from a moving
    state, against MuJoCo's RK4 at dt = 1e-4 (its own error ~1e-11 here)."""
    model = mujoco.MjModel.from_xml_string(ARM)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    data.qpos[:2] = rng.normal(size=2) * 0.5
    data.qpos[2:6] = bd.lie.quaternion_from_rotation_vector(rng.normal(size=3) * 0.4)
    data.qvel[:] = rng.normal(size=model.nv)
    qpos0, qvel0 = data.qpos.copy(), data.qvel.copy()
    mujoco.mj_forward(model, data)
    root = np.eye(4)
    root[:3, :3] = data.xmat[1].reshape(3, 3)
    root[:3, 3] = data.xpos[1]
    for _ in range(10000):
        mujoco.mj_step(model, data)
    arm = bd.Multibody.from_mjcf(ARM)
    start = bd.state_from_mujoco(arm, qpos0, qvel0, free_root=False, root_pose=root)
    scene = bd.Scene(arm, [bd.Gravity(9.81)], base=bd.PrescribedBase.fixed(root))
    traj = bd.simulate(scene, start, 1.0, rtol=1e-12, atol=1e-12)
    end = bd.State(traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
    qpos, qvel = bd.state_to_mujoco(arm, end, free_root=False)
    same_sign = np.sign(qpos[2]) * np.sign(data.qpos[2])
    np.testing.assert_allclose(qpos[:2], data.qpos[:2], atol=1e-9)
    np.testing.assert_allclose(same_sign * qpos[2:], data.qpos[2:], atol=1e-9)
    np.testing.assert_allclose(qvel, data.qvel, atol=1e-8)
    np.testing.assert_array_equal(traj.g[-1], root)


def test_energy_of_an_arm_on_a_fixed_base_is_conserved():
    """Gravity and a spring do no net work on a closed arm: kinetic plus potential energy
    stays to the solver's tolerance; a moving base does work, and the energy changes."""
    arm = SYSTEMS["chain5"]()
    effects = [bd.Gravity(), bd.ShapeSpring(2.0)]
    d = arm.shape_dim
    start = bd.State(jnp.eye(4), 0.3 * jnp.ones(d), jnp.zeros(6), -0.5 * jnp.ones(d))
    fixed = bd.simulate(bd.Scene(arm, effects, base=bd.PrescribedBase.fixed()), start, 2.0,
                        rtol=1e-11, atol=1e-11)  # fmt: skip
    energy = fixed.energy()
    assert abs(float(energy[-1] - energy[0])) < 1e-8 * float(jnp.abs(energy).max())

    def deck(t):  # a ship's deck heaving and rolling
        return bd.lie.se3_exp(jnp.array([0.1 * jnp.sin(t), 0, 0, 0, 0, 0.3 * jnp.sin(2 * t)]))

    moving = bd.simulate(bd.Scene(arm, effects, base=bd.PrescribedBase(deck)), start, 2.0,
                         saveat=diffrax.SaveAt(ts=jnp.linspace(0, 2, 5)))  # fmt: skip
    np.testing.assert_allclose(moving.g[-1], deck(2.0), atol=1e-12)
    assert abs(float(moving.energy()[-1] - moving.energy()[0])) > 1e-3


def test_a_prescribed_base_needs_a_free_shape_in_the_galilean_frame():
    arm = SYSTEMS["chain5"]()
    base = bd.PrescribedBase.fixed()
    with pytest.raises(ValueError, match="nothing would be left"):
        bd.Scene(arm, shape=bd.Prescribed(lambda t: jnp.zeros(arm.shape_dim) + t), base=base)
    with pytest.raises(ValueError, match="Galilean frame"):
        bd.Scene(arm, frame=bd.Boosted([1.0, 0, 0]), base=base)
    with pytest.raises(ValueError, match="free shape"):
        bd.Scene(SYSTEMS["rigid_body"](), base=base)
