"""MJCF/URDF import through MuJoCo's parser, checked against MuJoCo itself.

Forward kinematics against `mj_kinematics`; the metric against the kinetic energy summed
body by body from body velocities that MuJoCo's poses give by finite differences (and
against MuJoCo's own energy); the state converters both ways; the refusals and warnings.
"""

import pathlib
import warnings
from functools import partial
from typing import NamedTuple

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from systems import PASSIVE  # noqa: E402

import bundledyn  # noqa: E402
from bundledyn import Multibody  # noqa: E402
from bundledyn.lie import (  # noqa: E402
    quaternion_from_rotation_vector as _quaternion_from_rotation_vector,
    rotation_vector_from_quaternion as _rotation_vector_from_quaternion,
)

multibody_from_mjcf = Multibody.from_mjcf
multibody_from_urdf = Multibody.from_urdf

FREE, BALL, SLIDE, HINGE = 0, 1, 2, 3  # mjtJoint
MODELS = pathlib.Path(bundledyn.__file__).parent / "models"

# Jitted once for the whole module; the system is a pytree argument.


def _state_parts(system, qpos, qvel, *, qpos0=None, free_root=True, root_pose=None):
    state = bundledyn.state_from_mujoco(
        system, qpos, qvel, qpos0=qpos0, free_root=free_root, root_pose=root_pose
    )
    return state.g, state.q, state.xi, state.qdot


def _from_parts(system, g, q, xi, qdot, *, qpos0=None, free_root=True):
    state = bundledyn.State(g, q, xi, qdot)
    return bundledyn.state_to_mujoco(system, state, qpos0=qpos0, free_root=free_root)


to_state = jax.jit(_state_parts, static_argnames=("free_root",))
to_mujoco = jax.jit(_from_parts, static_argnames=("free_root",))
body_poses = jax.jit(lambda system, q: system.body_poses(q))


metric = jax.jit(lambda system, q: system.metric(q))


@partial(jax.jit, static_argnames=("free_root",))
def velocity_jacobian(system, qpos, qvel, qpos0, free_root=True):
    """P, the linear map from MuJoCo's qvel to bundledyn's (ξ, q̇) at `qpos`: the Jacobian
    of `state_from_mujoco`, compiled once per model (its states traced)."""

    def velocity(qvel):
        state = bundledyn.state_from_mujoco(system, qpos, qvel, qpos0=qpos0, free_root=free_root)
        return jnp.concatenate([state.xi, state.qdot])

    return jax.jacfwd(velocity)(qvel)


@jax.jit
def kinetic_energy(system, q, xi, qdot):
    z = jnp.concatenate([xi, qdot])
    return 0.5 * z @ system.metric(q) @ z


class Setup(NamedTuple):
    model: object
    system: Multibody


def _quiet(fn, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args)


@pytest.fixture(scope="module")
def chain():
    path = MODELS / "chain5.xml"
    return Setup(mujoco.MjModel.from_xml_path(str(path)), _quiet(multibody_from_mjcf, path))


@pytest.fixture(scope="module")
def tree():
    path = MODELS / "tree4.xml"
    return Setup(mujoco.MjModel.from_xml_path(str(path)), multibody_from_mjcf(str(path)))


def _urdf_reference_model(path):
    """MuJoCo's own compilation of the URDF, with the free root the importer documents."""
    spec = mujoco.MjSpec.from_file(str(path))
    spec.worldbody.first_body().add_freejoint()
    return spec.compile()


@pytest.fixture(scope="module")
def arm():
    path = MODELS / "arm.urdf"
    return Setup(_urdf_reference_model(path), _quiet(multibody_from_urdf, path))


# --------------------------------------------------------------------------------------
# helpers on the MuJoCo side
# --------------------------------------------------------------------------------------


def random_state(model, rng, angle=np.pi):
    """A random qpos (random unit quaternions of either sign) and qvel."""
    qpos = model.qpos0.copy()
    for j in range(model.njnt):
        a, t = model.jnt_qposadr[j], int(model.jnt_type[j])
        if t == FREE:
            qpos[a : a + 3] = rng.normal(size=3)
            quat = rng.normal(size=4)
            qpos[a + 3 : a + 7] = quat / np.linalg.norm(quat)
        elif t == BALL:
            quat = rng.normal(size=4)
            qpos[a : a + 4] = quat / np.linalg.norm(quat)
        elif t == HINGE:
            qpos[a] += rng.uniform(-angle, angle)
        else:
            qpos[a] += 0.2 * rng.normal()
    return qpos, rng.normal(size=model.nv)


def passive_forces_at_random_states(model, *, seed, angle, count=3):
    """MuJoCo's passive forces (`qfrc_spring + qfrc_damper`) at `count` random states:
    `(data, force)` pairs, `data` holding the state."""
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    for _ in range(count):
        data.qpos[:], data.qvel[:] = random_state(model, rng, angle=angle)
        mujoco.mj_forward(model, data)
        yield data, data.qfrc_spring + data.qfrc_damper


def mujoco_poses(model, data, qpos):
    """World poses of all MuJoCo bodies after `mj_kinematics`, shape (nbody, 4, 4)."""
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    T = np.tile(np.eye(4), (model.nbody, 1, 1))
    T[:, :3, :3] = data.xmat.reshape(-1, 3, 3)
    T[:, :3, 3] = data.xpos
    return T


def body_ids(setup):
    return [setup.model.body(name).id for name in setup.system.names]


def fd_kinetic_energy(model, qpos, qvel, h=3e-4):
    """½ Σ_a (m_a |v_c|² + ω·J_c ω) from body twists g⁻¹ġ by 4th-order central differences.

    The curve is qpos(t) = mj_integratePos(qpos, qvel, t) (exact exponential steps for
    quaternions), so ġ(0) is the velocity MuJoCo's qvel gives every body. Inertias come
    from MuJoCo's body arrays directly.
    """
    data = mujoco.MjData(model)

    def poses(t):
        qp = qpos.copy()
        mujoco.mj_integratePos(model, qp, qvel, t)
        return mujoco_poses(model, data, qp)

    G0 = poses(0.0)
    Gdot = (-poses(2 * h) + 8 * poses(h) - 8 * poses(-h) + poses(-2 * h)) / (12 * h)
    energy = 0.0
    for a in range(1, model.nbody):
        X = np.linalg.solve(G0[a], Gdot[a])  # g⁻¹ ġ
        W = 0.5 * (X[:3, :3] - X[:3, :3].T)
        omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
        v = X[:3, 3]
        m, c = model.body_mass[a], model.body_ipos[a]
        Ri = np.zeros(9)
        mujoco.mju_quat2Mat(Ri, model.body_iquat[a])
        Ri = Ri.reshape(3, 3)
        Jc = Ri @ np.diag(model.body_inertia[a]) @ Ri.T
        v_com = v + np.cross(omega, c)
        energy += 0.5 * (m * v_com @ v_com + omega @ Jc @ omega)
    return energy


def mujoco_energy(model, qpos, qvel):
    """MuJoCo's own kinetic energy ½ qvelᵀ M qvel (mjENBL_ENERGY)."""
    data = mujoco.MjData(model)
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    return data.energy[1]


def same_quaternions(model, qpos_a, qpos_b):
    """Flip the quaternion blocks of qpos_b to the sign of qpos_a's."""
    out = np.array(qpos_b, copy=True)
    for j in range(model.njnt):
        t, a = model.jnt_type[j], model.jnt_qposadr[j]
        s = {
            FREE: slice(a + 3, a + 7),
            BALL: slice(a, a + 4),
        }.get(int(t))
        if s is not None and np.dot(qpos_a[s], out[s]) < 0:
            out[s] = -out[s]
    return out


# --------------------------------------------------------------------------------------
# structure
# --------------------------------------------------------------------------------------


def test_chain_structure(chain):
    s = chain.system
    assert s.names == ("torso", "upper", "fore", "wrist", "slider", "gripper")
    assert s.parents == (-1, 0, 1, 2, 3, 4)
    assert s.joint_types == (
        "free",
        "revolute",
        "spherical",
        "universal",
        "prismatic",
        "composite",
    )
    assert s.shape_dim == chain.model.nv - 6
    assert np.allclose(s.mass, chain.model.body_mass[1:])
    # The wrist's hinge axes meet at (0.01, 0.6, 0), away from both joint positions.
    wrist = s.screw_axes[1:3]  # screws: shoulder, wrist x2, extend, twist, squeeze
    anchor = np.array([0.01, 0.6, 0.0])
    for S in np.asarray(wrist):
        assert np.allclose(S[3:], np.cross(anchor, S[:3]), atol=1e-12)


def test_tree_structure_welds_massless_frames(tree):
    s = tree.system
    assert "mount" not in s.names
    assert s.names == ("pelvis", "left_thigh", "left_shin", "right_thigh", "right_shin")
    assert s.parents == (-1, 0, 1, 0, 3)
    assert s.joint_types == ("free", "revolute", "revolute", "spherical", "prismatic")


def test_joint_mapping_of_two_hinges():
    def joint_of(j2):
        xml = f"""<mujoco><compiler angle="radian"/><worldbody><body><freejoint/>
        <geom size="0.1" contype="0" conaffinity="0"/><body pos="0 0 -1">
        <joint type="hinge" axis="1 0 0" pos="0 0 0.1"/>{j2}
        <geom size="0.1" contype="0" conaffinity="0"/></body></body></worldbody></mujoco>"""
        return multibody_from_mjcf(xml).joint_types[1]

    assert joint_of('<joint type="hinge" axis="0 1 1" pos="0 0 0.1"/>') == "universal"
    assert joint_of('<joint type="hinge" axis="0 1 0" pos="0 0 0.3"/>') == "composite"  # skew
    assert joint_of('<joint type="hinge" axis="1 0 0" pos="0 1 0"/>') == "composite"  # parallel
    assert joint_of('<joint type="slide" axis="0 1 0"/>') == "composite"
    assert joint_of('<joint type="ball"/>') == "composite"
    assert joint_of("") == "revolute"


def test_from_mjcf_classmethod_and_xml_string(tree):
    text = (MODELS / "tree4.xml").read_text()
    for system in (Multibody.from_mjcf(text), Multibody.from_mjcf(MODELS / "tree4.xml")):
        assert system.names == tree.system.names
        for a, b in zip(jax.tree.leaves(system), jax.tree.leaves(tree.system), strict=True):
            np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------------------
# forward kinematics
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["chain", "tree", "arm"])
def test_forward_kinematics_matches_mujoco(name, request):
    setup = request.getfixturevalue(name)
    model, system = setup.model, setup.system
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    ids = body_ids(setup)
    for _ in range(5):
        qpos, qvel = random_state(model, rng)
        T_mj = mujoco_poses(model, data, qpos)[ids]
        g, q, _, _ = to_state(system, qpos, qvel, qpos0=model.qpos0)
        T = np.asarray(g @ body_poses(system, q))
        np.testing.assert_allclose(T, T_mj, rtol=0, atol=1e-12)


def test_home_pose_is_qpos0(chain):
    """q = 0 is MuJoCo's qpos0 (joint refs included): the placements are the home pose."""
    model, system = chain.model, chain.system
    data = mujoco.MjData(model)
    T_mj = mujoco_poses(model, data, model.qpos0)[body_ids(chain)]
    g, q, _, _ = to_state(system, model.qpos0, np.zeros(model.nv), qpos0=model.qpos0)
    assert np.all(q == 0)
    np.testing.assert_allclose(g @ body_poses(system, q), T_mj, atol=1e-14)


# --------------------------------------------------------------------------------------
# the metric against the kinetic energy (the key test)
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["chain", "tree", "arm"])
def test_metric_is_kinetic_energy_of_mujoco_bodies(name, request):
    """½[ξ;q̇]ᵀG(q)[ξ;q̇] = ½Σ νₐᵀMₐνₐ with νₐ = gₐ⁻¹ġₐ from MuJoCo's poses by 4th-order
    central differences (h = 3e-4, along mj_integratePos; error ~1e-12 relative), and equals
    MuJoCo's own energy ½ qvelᵀ M qvel to rounding."""
    setup = request.getfixturevalue(name)
    model, system = setup.model, setup.system
    rng = np.random.default_rng(2)
    for _ in range(4):
        qpos, qvel = random_state(model, rng)
        _, q, xi, qdot = to_state(system, qpos, qvel, qpos0=model.qpos0)
        T = float(kinetic_energy(system, q, xi, qdot))
        T_fd = fd_kinetic_energy(model, qpos, qvel)
        T_mj = mujoco_energy(model, qpos, qvel)
        assert abs(T - T_fd) <= 1e-10 * T_fd, (T, T_fd)
        assert abs(T - T_mj) <= 1e-12 * T_mj, (T, T_mj)


# An ant-like tree: free root, hinges and a slide with rotor inertia (MuJoCo's armature,
# from a default class as in gymnasium's ant.xml, and per joint), a ball without.
ROTORS = """<mujoco><option gravity="0 0 0" integrator="RK4" timestep="1e-4"/>
<default><joint armature="0.7"/></default><worldbody><body name="torso"><freejoint/>
<inertial pos="0.01 0 0" mass="2" diaginertia="0.1 0.2 0.3"/>
<body name="a" pos="0.3 0 0"><joint type="hinge" axis="0 0 1"/>
<inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.02 0.02"/>
<body name="b" pos="0.3 0 0"><joint type="hinge" axis="0 1 0" armature="1.3"/>
<joint type="slide" axis="1 0 0" armature="0.2"/>
<inertial pos="0.1 0 0.02" mass="0.4" diaginertia="0.01 0.02 0.03"/></body></body>
<body name="c" pos="-0.3 0 0"><joint type="ball" armature="0"/>
<inertial pos="-0.1 0 0" mass="0.5" diaginertia="0.01 0.02 0.02"/></body>
</body></worldbody></mujoco>"""


def test_rotor_inertia_is_mujocos_armature():
    """The hinges' and the slide's armature is kept (no warning) and enters the metric:
    the kinetic energy equals MuJoCo's ½ qvelᵀ M qvel, whose M includes it, to rounding,
    and exceeds the bodies' own energy (from their poses by finite differences) by exactly
    ½ Σ aⱼ q̇ⱼ²."""
    model = mujoco.MjModel.from_xml_string(ROTORS)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        system = Multibody.from_mjcf(ROTORS)
    np.testing.assert_array_equal(system.armature, [0.7, 1.3, 0.2, 0, 0, 0])
    rng = np.random.default_rng(3)
    for _ in range(3):
        qpos, qvel = random_state(model, rng)
        _, q, xi, qdot = to_state(system, qpos, qvel, qpos0=model.qpos0)
        T = float(kinetic_energy(system, q, xi, qdot))
        T_mj = mujoco_energy(model, qpos, qvel)
        rotors = 0.5 * float(np.sum(model.dof_armature * qvel**2))
        assert rotors > 0.05 * T_mj
        assert abs(T - T_mj) <= 1e-12 * T_mj, (T, T_mj)
        T_bodies = fd_kinetic_energy(model, qpos, qvel)
        assert abs(T - T_bodies - rotors) <= 1e-10 * T_mj


def test_a_model_with_rotor_inertia_moves_as_mujoco_moves_it():
    """1 s of the tree, gravity off: bundledyn at rtol 1e-12 and MuJoCo's RK4 at dt = 1e-4
    end in the same state to within RK4's own error (measured 1e-14; without the armature
    in the metric the two differ by 0.6 in qpos)."""
    model = mujoco.MjModel.from_xml_string(ROTORS)
    system = Multibody.from_mjcf(ROTORS)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(4)
    data.qpos[:], data.qvel[:] = random_state(model, rng, angle=0.5)
    start = bundledyn.state_from_mujoco(system, data.qpos, data.qvel, qpos0=model.qpos0)
    for _ in range(10_000):
        mujoco.mj_step(model, data)
    traj = bundledyn.simulate(bundledyn.Scene(system), start, 1.0, rtol=1e-12, atol=1e-12)
    end = bundledyn.State(traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
    qpos, qvel = bundledyn.state_to_mujoco(system, end, qpos0=model.qpos0)
    np.testing.assert_allclose(same_quaternions(model, data.qpos, qpos), data.qpos, atol=1e-9)
    np.testing.assert_allclose(qvel, data.qvel, atol=1e-8)


def test_the_models_scene_moves_as_mujoco_moves_it_with_its_passive_forces_and_gravity():
    r"""`Scene.from_mjcf(..., passive=True, gravity=True)` maps the joints' dampers and
    springs (about springref, with a joint's ref), a fixed tendon's spring and damper and
    the model's gravity, and warns only about the tendon without passive force: with
    MuJoCo's limits off, 1 s of it equals MuJoCo's RK4 at dt = 1e-4 to within RK4's error
    (measured 2e-14; 0.13 apart without the tendon's spring and damper), and kinetic + potential energy falls
    by exactly what the dampers dissipate ($\int \dot q^T C \dot q\,dt$, Simpson's rule on
    2001 saved samples; measured 2e-11 of 0.9)."""
    model = mujoco.MjModel.from_xml_string(PASSIVE)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT  # limits: not modelled
    with pytest.warns(UserWarning) as record:
        scene = bundledyn.Scene.from_mjcf(PASSIVE, passive=True, gravity=True)
    (message,) = [str(w.message) for w in record if "ignored" in str(w.message)]
    assert "'couple' (no passive force" in message and "sinew" not in message
    assert "damping" not in message and "stiffness" not in message
    names = [type(e).__name__ for e in scene.effects]
    assert names == ["ShapeDamper", "ShapeSpring", "ShapeSpring", "Gravity"]
    system = scene.system
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = random_state(model, np.random.default_rng(5), angle=0.5)
    start = bundledyn.state_from_mujoco(system, data.qpos, data.qvel, qpos0=model.qpos0)
    for _ in range(10_000):
        mujoco.mj_step(model, data)
    ts = jnp.linspace(0.0, 1.0, 2001)
    saveat = diffrax.SaveAt(ts=ts)
    traj = bundledyn.simulate(scene, start, 1.0, saveat=saveat, rtol=1e-12, atol=1e-12)
    end = bundledyn.State(traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
    qpos, qvel = bundledyn.state_to_mujoco(system, end, qpos0=model.qpos0)
    np.testing.assert_allclose(qpos, same_quaternions(model, qpos, data.qpos), atol=1e-10)
    np.testing.assert_allclose(qvel, data.qvel, atol=1e-9)
    power = jnp.einsum("ti,ij,tj->t", traj.qdot, scene.effects[0].c, traj.qdot)
    h = float(ts[1] - ts[0])
    dissipated = h / 3 * (power[0] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum() + power[-1])
    energy = traj.energy()
    assert float(dissipated) > 0.5  # measured 0.9
    assert abs(float(energy[0] - energy[-1] - dissipated)) < 1e-9


def test_a_fixed_tendons_spring_and_damper_are_mujocos_passive_force():
    r"""The tendon's spring and damper, on their own, give MuJoCo's tendon passive force
    $-J^T(k\,(L - L_s) + b\,\dot L)$ (`qfrc_spring + qfrc_damper` with the joints' own
    springs and dampers switched off) at random states, to rounding: the rank-one
    `ShapeSpring`'s rest shape carries the spring length and the joints' refs."""
    model = mujoco.MjModel.from_xml_string(PASSIVE)
    model.jnt_stiffness[:] = 0.0
    model.dof_damping[:] = 0.0
    model.opt.gravity[:] = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tendon without passive force, a joint's ref
        scene = bundledyn.Scene.from_mjcf(model, passive=True)
    assert [type(e).__name__ for e in scene.effects] == ["ShapeDamper", "ShapeSpring"]
    for data, force in passive_forces_at_random_states(model, seed=6, angle=0.8):
        state = bundledyn.state_from_mujoco(scene.system, data.qpos, data.qvel, qpos0=model.qpos0)
        _, Q = scene.forces(bundledyn.Kinematics(0.0, state.g, state.q, state.xi, state.qdot))
        # The tendon's joints are hinges and the slide (MuJoCo dofs 6-9, shape coordinates 0-3).
        assert np.max(np.abs(force[6:10])) > 0.1
        np.testing.assert_allclose(Q[:4], force[6:10], rtol=1e-13, atol=1e-14)
        np.testing.assert_array_equal(Q[4:], 0.0)


@pytest.mark.parametrize("xml", ["PASSIVE", "ROTORS"])
def test_metric_is_mujocos_mass_matrix(xml):
    r"""On the gymnasium-style models (rotor inertia, ball joints): $P^T G(q) P$ equals
    MuJoCo's `mj_fullM` to 1e-12 relative at random states, $P$ the linear map from
    MuJoCo's qvel to bundledyn's $(\xi, \dot q)$ (a Jacobian of `state_from_mujoco`)."""
    xml = {"PASSIVE": PASSIVE, "ROTORS": ROTORS}[xml]
    model = mujoco.MjModel.from_xml_string(xml)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tendon without passive force
        system = Multibody.from_mjcf(xml)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    for _ in range(3):
        qpos, qvel = random_state(model, rng)
        P = np.asarray(velocity_jacobian(system, qpos, qvel, model.qpos0))
        state = bundledyn.state_from_mujoco(system, qpos, qvel, qpos0=model.qpos0)
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, M)
        ours = P.T @ np.asarray(metric(system, state.q)) @ P
        assert np.linalg.norm(ours - M) <= 1e-12 * np.linalg.norm(M)


@pytest.mark.parametrize(
    "armature, match",
    [([1.0, 0.5], "shape"), ([-0.1, 0, 0, 0], "non-negative"), ([0.1, 0.2, 0, 0], "ball joint")],
)
def test_a_bad_rotor_inertia_is_refused_with_the_fix(armature, match):
    body = bundledyn.RigidBody(1.0, [0.0, 0.0, 0.0], np.diag([0.1, 0.2, 0.3]))
    links = [
        bundledyn.Link(body, bundledyn.Revolute([0, 0, 1]), 0, np.eye(4)),
        bundledyn.Link(body, bundledyn.Spherical(), 1, np.eye(4)),
    ]
    assert Multibody(body, links, armature=[0.5, 0, 0, 0]).shape_dim == 4
    with pytest.raises(ValueError, match=match):
        Multibody(body, links, armature=armature)


def test_section_change_keeps_state_meaning(chain):
    """With another section body, g and ξ refer to its frame; FK and energy are unchanged."""
    model = chain.model
    system = _quiet(partial(multibody_from_mjcf, section="wrist"), model)
    assert system.section == 3
    rng = np.random.default_rng(3)
    data = mujoco.MjData(model)
    qpos, qvel = random_state(model, rng)
    g, q, xi, qdot = to_state(system, qpos, qvel, qpos0=model.qpos0)
    np.testing.assert_allclose(
        g @ body_poses(system, q), mujoco_poses(model, data, qpos)[body_ids(chain)], atol=1e-12
    )
    T = float(kinetic_energy(system, q, xi, qdot))
    T_mj = mujoco_energy(model, qpos, qvel)
    assert abs(T - T_mj) <= 1e-12 * T_mj
    qpos2, qvel2 = to_mujoco(system, g, q, xi, qdot, qpos0=model.qpos0)
    np.testing.assert_allclose(same_quaternions(model, qpos, qpos2), qpos, atol=1e-12)
    np.testing.assert_allclose(qvel2, qvel, atol=1e-12)


# --------------------------------------------------------------------------------------
# converters
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["chain", "tree"])
def test_round_trip_from_mujoco(name, request):
    setup = request.getfixturevalue(name)
    model, system = setup.model, setup.system
    rng = np.random.default_rng(4)
    for _ in range(5):
        qpos, qvel = random_state(model, rng)
        qpos2, qvel2 = to_mujoco(
            system, *to_state(system, qpos, qvel, qpos0=model.qpos0), qpos0=model.qpos0
        )
        np.testing.assert_allclose(same_quaternions(model, qpos, qpos2), qpos, atol=1e-13)
        np.testing.assert_allclose(qvel2, qvel, atol=1e-13)


def test_round_trip_from_state(chain):
    system = chain.system
    rng = np.random.default_rng(5)
    d = system.shape_dim
    g = bundledyn.lie.se3_exp(rng.normal(size=6))
    q = rng.normal(size=d)
    # ball coordinates inside the principal ball |φ| < π
    kinds, starts = system.tables.kinds, system.tables.q_start
    for kind, s in zip(kinds, starts, strict=True):
        if kind == "ball":
            q[s : s + 3] *= 2.0 / np.linalg.norm(q[s : s + 3])
    xi, qdot = rng.normal(size=6), rng.normal(size=d)
    qpos0 = chain.model.qpos0
    state2 = to_state(system, *to_mujoco(system, g, q, xi, qdot, qpos0=qpos0), qpos0=qpos0)
    for a, b in zip((g, q, xi, qdot), state2, strict=True):
        np.testing.assert_allclose(b, a, atol=1e-12)


def test_converters_jit_vmap_grad(chain):
    system, model = chain.system, chain.model
    qpos0 = model.qpos0
    rng = np.random.default_rng(6)
    batch = [random_state(model, rng) for _ in range(6)]
    qpos = np.stack([b[0] for b in batch])
    qvel = np.stack([b[1] for b in batch])

    def both_ways(qpos, qvel):
        state = _state_parts(system, qpos, qvel, qpos0=qpos0)
        return state, _from_parts(system, *state, qpos0=qpos0)

    state, (_, qvel2) = jax.jit(jax.vmap(both_ways))(qpos, qvel)
    for i in range(len(batch)):
        ref = to_state(system, qpos[i], qvel[i], qpos0=qpos0)
        for a, b in zip(state, ref, strict=True):
            np.testing.assert_allclose(a[i], b, atol=1e-14)
    np.testing.assert_allclose(qvel2, qvel, atol=1e-13)

    # Derivatives are finite at the home pose (ball quaternion = identity, φ = 0), both ways.
    @jax.jit
    def derivatives(qpos, qvel):
        grads = jax.grad(lambda *a: sum(jnp.sum(x) for x in both_ways(*a)[0]), (0, 1))
        state = _state_parts(system, qpos, qvel, qpos0=qpos0)
        tangents = tuple(jnp.ones_like(x) for x in state)
        _, jvp = jax.jvp(lambda *s: _from_parts(system, *s, qpos0=qpos0), state, tangents)
        return grads(qpos, qvel), jvp

    out = derivatives(qpos0, qvel[0])
    assert all(np.all(np.isfinite(x)) for x in jax.tree.leaves(out))


@jax.jit  # one program, not one per primitive
def _ball_coordinates(quats, identity, zero):
    """φ of `quats`, exp(φ̃), R(quat), the quaternion of φ back, and the Jacobians both ways at
    the identity (`identity`, φ = `zero`)."""
    phi = _rotation_vector_from_quaternion(quats)
    return (
        phi,
        bundledyn.lie.so3_exp(phi),
        bundledyn.lie.rotation_from_quaternion(quats),
        _quaternion_from_rotation_vector(phi),
        jax.jacfwd(_rotation_vector_from_quaternion)(identity),
        jax.jacfwd(_quaternion_from_rotation_vector)(zero),
    )


def test_ball_coordinates_of_quaternions():
    """φ of a quaternion: exp(φ̃) = R(quat), |φ| ≤ π, both signs, near 0 and near π, exact
    derivatives at φ = 0."""
    rng = np.random.default_rng(8)
    quats = rng.normal(size=(200, 4))
    quats[:20, 1:] *= 1e-4  # near the identity, either sign of w
    quats[20:40, 0] *= 1e-7  # near a half turn
    quats[40:43] = [[1, 0, 0, 0], [-1, 0, 0, 0], [0, 0, 1, 0]]
    phi, exp_phi, R, back, J_phi, J_quat = (
        np.asarray(x)
        for x in _ball_coordinates(jnp.asarray(quats), jnp.array([1.0, 0, 0, 0]), jnp.zeros(3))
    )
    np.testing.assert_allclose(exp_phi, R, atol=2e-15)
    assert np.all(np.linalg.norm(phi, axis=-1) <= np.pi + 1e-15)
    unit = quats / np.linalg.norm(quats, axis=-1, keepdims=True)
    np.testing.assert_allclose(back * np.sign(np.sum(back * unit, -1))[:, None], unit, atol=1e-15)
    np.testing.assert_allclose(J_phi, np.hstack([np.zeros((3, 1)), 2 * np.eye(3)]), atol=1e-15)
    np.testing.assert_allclose(J_quat, np.vstack([np.zeros((1, 3)), 0.5 * np.eye(3)]), atol=1e-15)


# A root without a joint, which MuJoCo welds to the world, at a tilted pose; damped hinges
# (one with a ref and rotor inertia), a ball joint and gravity off the vertical.
WELDED = """<mujoco><compiler angle="radian"/>
<option gravity="0.5 -1 -9.81" integrator="RK4" timestep="1e-4"/><worldbody>
<body name="base" pos="0.1 0.2 0.3" quat="0.9 0.2 0.1 0"><inertial pos="0 0 0" mass="2"
 diaginertia="0.1 0.1 0.1"/>
<body name="arm" pos="0 0 -0.5"><joint type="hinge" axis="0 1 0" ref="0.2" damping="0.3"
 armature="0.1"/><inertial pos="0 0 -0.2" mass="1" diaginertia="0.02 0.02 0.01"/>
<body name="hand" pos="0 0 -0.4"><joint type="ball"/>
<inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.008 0.005"/></body></body>
<body name="tail" pos="0.2 0 0"><joint type="hinge" axis="1 0 0" damping="0.2"/>
<inertial pos="0.15 0 0" mass="0.7" diaginertia="0.01 0.02 0.02"/></body>
</body></worldbody></mujoco>"""


# Roots attached to the world by joints, as dm_control's and gymnasium's planar and
# fixed-base models attach theirs: a double pendulum hung by a hinge (rotor inertia, a
# damper), a cart-pole on a slide (a spring with a rest position on the pole), a planar
# walker whose torso moves by two slides and a hinge (MuJoCo's rootx, rootz, rooty) with
# two legs, a spherical pendulum on a ball joint; gravity off the vertical in one.
ATTACHED = {
    "pendulum": """<mujoco><option gravity="0 0 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="pole" pos="0 0 1" quat="0.9 0.1 0.2 0">
<joint name="swing" type="hinge" axis="0 1 0" damping="0.1" armature="0.02"/>
<inertial pos="0 0 -0.4" mass="1.2" fullinertia="0.05 0.06 0.02 0.001 0 0.002"/>
<body name="tip" pos="0 0 -0.8"><joint name="tip" type="hinge" axis="1 0 0.2"/>
<inertial pos="0 0.05 -0.1" mass="0.3" diaginertia="0.01 0.01 0.002"/></body>
</body></worldbody></mujoco>""",
    "cartpole": """<mujoco><option gravity="0.3 0 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="cart" pos="0 0 0.5">
<joint name="slider" type="slide" axis="1 0 0" damping="0.2"/>
<inertial pos="0 0 0" mass="2" diaginertia="0.1 0.2 0.1"/>
<body name="pole"><joint name="hinge" type="hinge" axis="0 1 0" stiffness="1" springref="0.1"/>
<inertial pos="0 0 0.3" mass="0.4" diaginertia="0.02 0.02 0.001"/></body>
</body></worldbody></mujoco>""",
    "walker": """<mujoco><option gravity="0 0 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="torso" pos="0 0 1.2">
<joint name="rootx" type="slide" axis="1 0 0"/><joint name="rootz" type="slide" axis="0 0 1"/>
<joint name="rooty" type="hinge" axis="0 1 0"/>
<inertial pos="0 0 0.1" mass="3.5" diaginertia="0.1 0.12 0.05"/>
<body name="thigh" pos="0 0 -0.2"><joint name="hip" type="hinge" axis="0 -1 0" damping="0.1"/>
<inertial pos="0 0 -0.2" mass="1" diaginertia="0.02 0.02 0.004"/>
<body name="leg" pos="0 0 -0.45"><joint name="knee" type="hinge" axis="0 -1 0"/>
<inertial pos="0 0 -0.2" mass="0.6" diaginertia="0.01 0.01 0.002"/></body></body>
<body name="other_thigh" pos="0 0 -0.2"><joint name="other_hip" type="hinge" axis="0 -1 0"/>
<inertial pos="0.02 0 -0.2" mass="1" diaginertia="0.02 0.02 0.004"/></body>
</body></worldbody></mujoco>""",
    # Several trees, as dm_control's finger (a finger and its spinner), ball_in_cup (a cup
    # and a ball, each on two slides) and gymnasium's pusher (an arm and an object) hang
    # theirs: two hinged trees, one on slides, a massive mount welded to the world, and a
    # spring-damper string from the mount's site to the ball's.
    "several": """<mujoco><option gravity="0 0.4 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="proximal" pos="0 0.2 0.6" quat="0.9 0 0.3 0.1">
<joint name="root" type="hinge" axis="0 1 0" damping="0.05" armature="0.01"/>
<inertial pos="0 0 -0.1" mass="0.5" diaginertia="0.01 0.01 0.002"/>
<body name="distal" pos="0 0 -0.2"><joint name="joint" type="hinge" axis="0 1 0.3"/>
<inertial pos="0 0.02 -0.1" mass="0.3" diaginertia="0.005 0.006 0.001"/></body></body>
<body name="spinner" pos="0.2 0 0.4"><joint name="hinge" type="hinge" axis="0 1 0"
 stiffness="0.3" springref="0.2"/>
<inertial pos="0.05 0 0" mass="0.2" diaginertia="0.002 0.003 0.002"/></body>
<body name="mount" pos="-0.3 0 0.5"><inertial pos="0 0 0" mass="4" diaginertia="1 1 1"/>
<site name="anchor" pos="0 0 0.1"/></body>
<body name="ball" pos="-0.3 0 0.2"><joint name="ball_x" type="slide" axis="1 0 0"/>
<joint name="ball_z" type="slide" axis="0 0 1" damping="0.1"/>
<inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/><site name="bead"/></body>
</worldbody><tendon><spatial name="string" stiffness="2" damping="0.05" springlength="0.25">
<site site="anchor"/><site site="bead"/></spatial></tendon></mujoco>""",
    # Several trees that float, as dm_control's dog and its ball: a two-body tree and a
    # ball, each on a free joint (placed and turned at home), and a pendulum on a hinge.
    "floating": """<mujoco><option gravity="0 0 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="torso" pos="0.3 -0.2 1" quat="0.8 0.2 0.3 0.1"><freejoint/>
<inertial pos="0.05 0 0" mass="3" fullinertia="0.1 0.12 0.05 0.01 0 0.003"/>
<body name="leg" pos="0 0 -0.3"><joint name="hip" type="hinge" axis="0 1 0.2" damping="0.1"/>
<inertial pos="0 0 -0.1" mass="0.5" diaginertia="0.01 0.01 0.002"/></body></body>
<body name="ball" pos="1 0 0.5"><freejoint/>
<inertial pos="0 0 0" mass="0.2" diaginertia="0.002 0.002 0.002"/></body>
<body name="pole" pos="0 1 1"><joint name="swing" type="hinge" axis="1 0 0"/>
<inertial pos="0 0 -0.3" mass="0.4" diaginertia="0.01 0.01 0.001"/></body>
</worldbody></mujoco>""",
    "spherical": """<mujoco><option gravity="0 0 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="bob" pos="0.1 0 1"><joint name="pivot" type="ball"/>
<inertial pos="0.1 0.05 -0.5" mass="0.8" diaginertia="0.02 0.03 0.01"/></body>
</worldbody></mujoco>""",
}


def _held_base_cases():
    """The welded root and the attached ones: the model, and where the base is held."""
    cases = [pytest.param(WELDED, "root", id="welded")]
    return cases + [pytest.param(xml, "world", id=name) for name, xml in ATTACHED.items()]


@pytest.mark.parametrize("xml, held", _held_base_cases())
def test_a_held_root_moves_as_mujoco_moves_it(xml, held):
    """MuJoCo's fixed bases: a root without a joint is welded to the world, and a root
    attached to the world by hinges, slides or a ball joint hangs from it. `Scene.from_mjcf`
    holds the base (the root at its pose; the world's stand-in at the world's frame), the
    shape block of the metric (with the rotor inertia) is MuJoCo's mass matrix to 1e-12,
    and 1 s with the model's gravity, springs and dampers equals MuJoCo's RK4 at
    dt = 1e-4 to 1e-9 while the base does not move."""
    model = mujoco.MjModel.from_xml_string(xml)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "joint.*non-zero reference", UserWarning)
        scene = bundledyn.Scene.from_mjcf(xml, passive=True, gravity=True)
    assert isinstance(scene.mode, bundledyn.PrescribedBaseMode)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = random_state(model, np.random.default_rng(3), angle=0.5)
    base = mujoco_poses(model, data, data.qpos.copy())[1] if held == "root" else np.eye(4)
    assert scene.system.names[0] == ("world" if held == "world" else model.body(1).name)
    system = scene.system
    start = bundledyn.state_from_mujoco(
        system, data.qpos, data.qvel, qpos0=model.qpos0, free_root=False
    )
    # The shape velocity's rows of the Jacobian (the section's are the held base's).
    P = np.asarray(
        velocity_jacobian(system, data.qpos.copy(), data.qvel.copy(), model.qpos0, free_root=False)
    )[6:]
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    ours = P.T @ np.asarray(metric(system, start.q))[6:, 6:] @ P
    assert np.linalg.norm(ours - M) <= 1e-12 * np.linalg.norm(M)
    for _ in range(10_000):
        mujoco.mj_step(model, data)
    saveat = diffrax.SaveAt(ts=jnp.linspace(0.0, 1.0, 5))
    traj = bundledyn.simulate(scene, start, 1.0, saveat=saveat, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(traj.g, np.broadcast_to(base, traj.g.shape), atol=1e-15)
    end = bundledyn.State(traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
    qpos, qvel = bundledyn.state_to_mujoco(system, end, qpos0=model.qpos0, free_root=False)
    np.testing.assert_allclose(qpos, same_quaternions(model, qpos, data.qpos), atol=1e-9)
    np.testing.assert_allclose(qvel, data.qvel, atol=1e-9)
    with pytest.raises(ValueError, match="freejoint"):
        _quiet(partial(bundledyn.Scene.from_mjcf, section=system.names[1]), xml)


def test_identification_frees_the_bodies_whose_inertia_enters_the_equations():
    """On a held base, the default free bodies leave out the base (the world's stand-in,
    or a welded root), whose inertia enters no equation; a floating base is fitted too."""
    from bundledyn import identify

    attached = _quiet(partial(bundledyn.Scene.from_mjcf, gravity=True), ATTACHED["walker"])
    assert identify.Parameters(attached).bodies == (1, 2, 3, 4)
    welded = _quiet(bundledyn.Scene.from_mjcf, WELDED)
    assert identify.Parameters(welded).bodies == (1, 2, 3)
    floating = bundledyn.Scene(welded.system)
    assert identify.Parameters(floating).bodies == (0, 1, 2, 3)


def test_a_model_with_gravity_turned_off_falls_not():
    """`<flag gravity="disable">` turns the model's gravity off: `Scene.from_mjcf(...,
    gravity=True)` says so and adds none, and the body keeps its velocity."""
    xml = """<mujoco><option gravity="0 0 -9.81"><flag gravity="disable"/></option>
    <worldbody><body><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="0.1 0.2 0.3"/>
    </body></worldbody></mujoco>"""
    with pytest.warns(UserWarning, match="turns gravity off"):
        scene = bundledyn.Scene.from_mjcf(xml, gravity=True)
    assert not scene.effects
    state = bundledyn.State(jnp.eye(4), xi=jnp.array([0.0, 0.0, 0.0, 0.3, 0.0, 1.0]))
    traj = bundledyn.simulate(scene, state, 1.0)
    np.testing.assert_allclose(traj.g[-1, :3, 3], [0.3, 0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("off", ["spring", "damper", "spring and damper"])
def test_a_model_that_turns_its_springs_or_dampers_off_gets_none(off):
    """`<flag spring="disable">` and `<flag damper="disable">`: `Scene.from_mjcf(...,
    passive=True)` says so and adds what the model keeps, whose shape force is MuJoCo's
    passive force (`qfrc_passive`) with the same flags."""
    kinds = off.split(" and ")
    flags = " ".join(f'{kind}="disable"' for kind in kinds)
    xml = ATTACHED["several"].replace(
        'timestep="1e-4"/>', f'timestep="1e-4"><flag {flags}/></option>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.warns(UserWarning, match=f"turns its {' and '.join(k + 's' for k in kinds)} off"):
        scene = bundledyn.Scene.from_mjcf(xml, passive=True)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = random_state(model, np.random.default_rng(5), angle=0.5)
    mujoco.mj_forward(model, data)
    state = bundledyn.state_from_mujoco(
        scene.system, data.qpos, data.qvel, qpos0=model.qpos0, free_root=False
    )
    term = bundledyn.SceneTerm(scene)
    kinematics = term.kinematics(0.0, term.encode(0.0, state))
    _, shape_force = scene.forces(kinematics)
    np.testing.assert_allclose(shape_force, data.qfrc_passive, rtol=0, atol=1e-12)
    assert np.any(data.qfrc_passive != 0) or off == "spring and damper"


def test_root_without_free_joint():
    """The tree of a root without a joint (`Multibody.from_mjcf`) is a system any scene may
    float (`Scene.from_mjcf` welds it, as MuJoCo does); free_root=False converts."""
    xml = """<mujoco><compiler angle="radian"/><worldbody>
      <body name="base" pos="0.1 0.2 0.3" quat="0.9 0.2 0.1 0"><inertial pos="0 0 0" mass="2"
          diaginertia="0.1 0.1 0.1"/>
        <body name="arm" pos="0 0 -0.5"><joint type="hinge" axis="0 1 0" ref="0.2"/>
          <inertial pos="0 0 -0.2" mass="1" diaginertia="0.02 0.02 0.01"/>
          <body name="hand" pos="0 0 -0.4"><joint type="ball"/>
            <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.008 0.005"/></body>
        </body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.warns(UserWarning, match="qpos0"):
        system = multibody_from_mjcf(xml)
    assert system.names == ("base", "arm", "hand")
    rng = np.random.default_rng(7)
    data = mujoco.MjData(model)
    qpos, qvel = random_state(model, rng)
    T_mj = mujoco_poses(model, data, qpos)
    g, q, xi, qdot = to_state(
        system, qpos, qvel, qpos0=model.qpos0, free_root=False, root_pose=T_mj[1]
    )
    assert np.all(xi == 0)
    np.testing.assert_allclose(g @ body_poses(system, q), T_mj[1:], atol=1e-12)
    T = float(kinetic_energy(system, q, xi, qdot))
    assert abs(T - mujoco_energy(model, qpos, qvel)) <= 1e-12 * T
    qpos2, qvel2 = to_mujoco(system, g, q, xi, qdot, qpos0=model.qpos0, free_root=False)
    np.testing.assert_allclose(same_quaternions(model, qpos, qpos2), qpos, atol=1e-13)
    np.testing.assert_allclose(qvel2, qvel, atol=1e-13)
    # The flag as NumPy gives it (`np.bool_`, e.g. read from a file of settings).
    state = bundledyn.state_from_mujoco(
        system, qpos, qvel, qpos0=model.qpos0, free_root=np.bool_(False), root_pose=T_mj[1]
    )
    np.testing.assert_array_equal(state.g, g)
    qpos3, _ = bundledyn.state_to_mujoco(
        system, state, qpos0=model.qpos0, free_root=np.array(False)
    )
    np.testing.assert_array_equal(qpos3, qpos2)
    with pytest.raises(TypeError, match="give True or False"):
        jax.jit(lambda flag: bundledyn.state_to_mujoco(system, state, free_root=flag)[0])(False)


def test_converter_shape_errors(tree):
    with pytest.raises(ValueError, match="qpos"):
        to_state(tree.system, np.zeros(13), np.zeros(12))
    with pytest.raises(ValueError, match="free_root=False"):
        to_state(tree.system, np.zeros(14), np.zeros(12), free_root=False)


# --------------------------------------------------------------------------------------
# URDF
# --------------------------------------------------------------------------------------


def test_a_urdf_scene_takes_its_joints_damping_and_standard_gravity(tmp_path):
    """`Scene.from_urdf(..., passive=True, gravity=True)`: a joint's `<dynamics damping>`
    is MuJoCo's joint damping, a `ShapeDamper` on its coordinate; its `friction` is listed
    as ignored; gravity is MuJoCo's default, 9.81 m/s² along -z (URDF states none)."""
    text = (MODELS / "arm.urdf").read_text()
    elbow = '<axis xyz="1 0 1"/></joint>'
    assert elbow in text
    damped = text.replace(
        elbow, '<axis xyz="1 0 1"/><dynamics damping="0.3" friction="0.1"/></joint>'
    )
    path = tmp_path / "arm.urdf"
    path.write_text(damped)
    with pytest.warns(UserWarning, match="friction loss of joint\\(s\\) 'elbow'") as record:
        scene = bundledyn.Scene.from_urdf(path, passive=True, gravity=True)
    assert "damping" not in str(record[0].message)
    damper, gravity = scene.effects
    np.testing.assert_array_equal(damper.c, [0.0, 0.3, 0.0])
    np.testing.assert_allclose(gravity.g * gravity.direction, [0.0, 0.0, -9.81], rtol=1e-15)
    with pytest.warns(UserWarning, match="damping of joint\\(s\\) 'elbow'"):
        assert bundledyn.Scene.from_urdf(path).effects == []


def test_urdf_structure(arm):
    s = arm.system
    # 'tool' is fused into 'fore' by MuJoCo (fixed joint, fusestatic).
    assert s.names == ("base", "upper", "fore", "slider")
    assert s.joint_types == ("free", "revolute", "revolute", "prismatic")
    np.testing.assert_allclose(s.mass, [2.0, 1.0, 0.8, 0.1])
    elbow = np.asarray(s.screw_axes[1, :3])
    np.testing.assert_allclose(elbow, np.array([1.0, 0.0, 1.0]) / np.sqrt(2), atol=1e-12)
    with pytest.warns(UserWarning, match="contacts of 1 collision geom"):
        again = Multibody.from_urdf(MODELS / "arm.urdf")
    assert again.names == s.names


# --------------------------------------------------------------------------------------
# refusals and warnings
# --------------------------------------------------------------------------------------

BODY = '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>'


def _xml(worldbody, extra=""):
    return f"<mujoco><worldbody>{worldbody}</worldbody>{extra}</mujoco>"


@pytest.mark.parametrize(
    ("xml", "match"),
    [
        (
            _xml(
                f"<body name='a'><freejoint/>{BODY}<body name='b'><freejoint/>{BODY}</body></body>"
            ),
            "free joint",
        ),
        (
            _xml(
                f"<body name='a'><freejoint/>{BODY}<body name='b'><joint/>{BODY}</body></body>",
                "<equality><connect name='loop' body1='b' body2='world' anchor='0 0 0'/>"
                "</equality>",
            ),
            "equality constraint.*other than joint couplings.*'loop'.*Remove those <equality>",
        ),
        (
            _xml(
                f"<body name='a'><freejoint/>{BODY}<body name='b'><joint name='j'/>{BODY}"
                "</body></body>",
                "<tendon><fixed name='t' armature='0.1'><joint joint='j' coef='1'/></fixed>"
                "</tendon>",
            ),
            "tendon.*'t'.*armature.*Set the tendons' armature to 0",
        ),
        (
            _xml(
                f"<body name='a'><freejoint/>{BODY}<body name='dummy'><joint name='j'/>"
                f"<body name='c'>{BODY}</body></body></body>"
            ),
            r"body 'dummy' carries joint\(s\) 'j' \(hinge\) but has no mass.*<inertial>",
        ),
        (
            _xml(f"<body name='a'><freejoint/><body name='b'>{BODY}</body></body>"),
            "root body 'a' has no mass",
        ),
        (
            _xml(f"<body name='a'><body name='b'><joint/>{BODY}</body></body>"),
            "root body 'a' has no mass",
        ),
        (
            _xml(f"<body name='pole'><joint name='pin'/><body name='c'>{BODY}</body></body>"),
            r"body 'pole' carries joint\(s\) 'pin' \(hinge\) but has no mass",
        ),
        (_xml("<geom size='1'/>"), "no body under the worldbody"),
    ],
)
def test_unsupported_elements_raise(xml, match):
    with pytest.raises(ValueError, match=match):
        multibody_from_mjcf(xml)


CHAIN = (
    f"<body name='a'><freejoint/>{BODY}<body name='b'><joint name='j' {{}}/>{BODY}</body></body>"
)


@pytest.mark.parametrize(
    ("xml", "match"),
    [
        (_xml(CHAIN.format("stiffness='2 0.5'")), r"joint\(s\) 'j' have nonlinear"),
        (_xml(CHAIN.format("damping='1 0.3'")), r"joint\(s\) 'j' have nonlinear"),
        (_xml(CHAIN.format("stiffness='2' springyield='1'")), r"joint\(s\) 'j' have nonlinear"),
        (
            _xml(
                CHAIN.format(""),
                "<tendon><fixed name='t' stiffness='2' springlength='0 0.2'>"
                "<joint joint='j' coef='1'/></fixed></tendon>",
            ),
            r"tendon\(s\) 't' have nonlinear.*dead band",
        ),
    ],
)
def test_nonlinear_passive_forces_are_refused_when_asked_for(xml, match):
    """A spring or damper that a linear `ShapeSpring`/`ShapeDamper` would get wrong raises
    when the passive forces are imported; without them it is only listed as ignored."""
    with pytest.raises(ValueError, match=match):
        bundledyn.Scene.from_mjcf(xml, passive=True)
    with pytest.warns(UserWarning, match="ignored"):
        bundledyn.Scene.from_mjcf(xml)


def test_bad_sources():
    with pytest.raises(FileNotFoundError):
        multibody_from_mjcf("no/such/model.xml")
    with pytest.raises(FileNotFoundError):
        multibody_from_urdf("no/such/robot.urdf")
    with pytest.raises(ValueError, match="MJCF"):
        multibody_from_mjcf(42)
    with pytest.raises(ValueError, match="MuJoCo could not compile"):
        multibody_from_mjcf(
            "<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody></mujoco>"
        )


def test_ignored_elements_warn_once():
    xml = _xml(
        "<geom type='plane' size='1 1 1'/>"
        f"<body><freejoint/>{BODY}<body name='b'><joint name='j' range='-1 1' damping='0.1'"
        f" armature='0.01' stiffness='2'/>{BODY}</body></body>",
        "<actuator><motor joint='j'/></actuator><sensor><jointpos joint='j'/></sensor>",
    )
    with pytest.warns(UserWarning) as record:
        multibody_from_mjcf(xml)
    assert len(record) == 1
    message = str(record[0].message)
    for word in (
        "contacts of 1 collision geom",
        "1 actuator",
        "1 sensor",
        "limits of joint(s) 'j'",
        "stiffness",
        "damping",
    ):
        assert word in message, (word, message)
    assert "armature" not in message  # a hinge's rotor inertia is kept


# Spatial tendons from site to site: on a floating arm, a muscle through three sites (one on
# a massless frame welded into its body) with a spring and a damper, and a string with a
# range only; on a pendulum hung by a hinge, a spring from a site of the world.
SPATIAL = """<mujoco><option gravity="0 0 0" integrator="RK4" timestep="1e-4"/><worldbody>
<body name="torso"><freejoint/><inertial pos="0 0 0" mass="2" diaginertia="0.1 0.12 0.08"/>
<site name="s0" pos="0.05 0.1 0"/>
<body name="upper" pos="0.3 0 0"><joint name="shoulder" type="hinge" axis="0 0 1"/>
<inertial pos="0.15 0 0" mass="1" diaginertia="0.01 0.02 0.02"/>
<body name="mount" pos="0.2 0 0.05"><site name="s1" pos="0 0.05 0"/></body>
<body name="lower" pos="0.3 0 0"><joint name="elbow" type="hinge" axis="0 1 0.3"/>
<inertial pos="0.1 0 0" mass="0.6" diaginertia="0.005 0.01 0.01"/>
<site name="s2" pos="0.2 -0.03 0.02"/></body></body></body></worldbody>
<tendon><spatial name="muscle" stiffness="40" damping="0.8" springlength="0.5">
<site site="s0"/><site site="s1"/><site site="s2"/></spatial>
<spatial name="string" limited="true" range="0 1"><site site="s0"/><site site="s2"/></spatial>
</tendon></mujoco>"""
TETHERED = """<mujoco><option gravity="0 0 -9.81" integrator="RK4" timestep="1e-4"/>
<worldbody><site name="anchor" pos="0.3 0 1.2"/><body name="pole" pos="0 0 1">
<joint name="pin" type="hinge" axis="0 1 0"/>
<inertial pos="0 0 -0.3" mass="1" diaginertia="0.03 0.03 0.002"/><site name="tip" pos="0 0 -0.6"/>
</body></worldbody><tendon><spatial name="tether" stiffness="15" damping="0.3" springlength="0.4">
<site site="anchor"/><site site="tip"/></spatial></tendon></mujoco>"""


@pytest.mark.parametrize("xml", ["SPATIAL", "TETHERED"])
def test_a_spatial_tendons_spring_and_damper_are_mujocos_passive_force(xml):
    r"""A spatial tendon's spring and damper give MuJoCo's passive force
    $-J^T(k\,(L - L_s) + b\,\dot L)$ (`qfrc_spring + qfrc_damper`) at random states, to
    rounding; on a floating tree, with no wrench on the base (the tendon is internal); the
    tendon without passive force is left out with a warning."""
    xml = {"SPATIAL": SPATIAL, "TETHERED": TETHERED}[xml]
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.gravity[:] = 0.0
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        scene = bundledyn.Scene.from_mjcf(model, passive=True)
    messages = " ".join(str(w.message) for w in record)
    assert ("'string' (no passive force" in messages) == (xml == SPATIAL)
    assert [type(e).__name__ for e in scene.effects] == ["TendonSpring", "TendonDamper"]
    floating = model.jnt_type[0] == FREE
    for data, force in passive_forces_at_random_states(model, seed=8, angle=1.0):
        state = bundledyn.state_from_mujoco(
            scene.system, data.qpos, data.qvel, free_root=bool(floating)
        )
        F, Q = scene.forces(bundledyn.Kinematics(0.0, state.g, state.q, state.xi, state.qdot))
        shape = force[6:] if floating else force
        assert np.max(np.abs(shape)) > 0.1
        np.testing.assert_allclose(Q, shape, rtol=1e-12, atol=1e-13)
        if floating:
            np.testing.assert_allclose(force[:6], 0.0, atol=1e-13)
            np.testing.assert_allclose(F, 0.0, atol=1e-13)


def test_a_floating_tree_moves_with_its_spatial_tendon_as_mujoco_moves_it():
    """1 s of the floating arm pulled by its muscle equals MuJoCo's RK4 at dt = 1e-4 to 1e-9."""
    model = mujoco.MjModel.from_xml_string(SPATIAL)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT  # the string's range
    scene = _quiet(partial(bundledyn.Scene.from_mjcf, passive=True), SPATIAL)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = random_state(model, np.random.default_rng(9), angle=0.8)
    start = bundledyn.state_from_mujoco(scene.system, data.qpos, data.qvel)
    for _ in range(10_000):
        mujoco.mj_step(model, data)
    traj = bundledyn.simulate(scene, start, 1.0, rtol=1e-12, atol=1e-12)
    end = bundledyn.State(traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
    qpos, qvel = bundledyn.state_to_mujoco(scene.system, end)
    np.testing.assert_allclose(qpos, same_quaternions(model, qpos, data.qpos), atol=1e-9)
    np.testing.assert_allclose(qvel, data.qvel, atol=1e-9)


def test_what_a_spatial_tendon_cannot_carry_is_refused():
    """With its passive forces asked for: a spring to a point of the world on a floating
    tree (an external force), and a tendon wrapping around a geom."""
    to_world = SPATIAL.replace('<site name="s0" pos="0.05 0.1 0"/>', "").replace(
        "<worldbody>", '<worldbody><site name="s0" pos="0.05 0.1 0"/>'
    )
    with pytest.raises(ValueError, match="site 's0'.*on the world.*root floats"):
        _quiet(partial(bundledyn.Scene.from_mjcf, passive=True), to_world)
    wrapped = SPATIAL.replace(
        '<site name="s1" pos="0 0.05 0"/>',
        '<site name="s1" pos="0 0.05 0"/><geom name="knob" type="sphere" size="0.02"/>',
    ).replace('<site site="s1"/>', '<geom geom="knob"/>')
    with pytest.raises(ValueError, match="'muscle'.*wrap around geoms"):
        _quiet(partial(bundledyn.Scene.from_mjcf, passive=True), wrapped)
    assert _quiet(bundledyn.Multibody.from_mjcf, wrapped).shape_dim == 2  # forces not asked


def test_a_fixed_tendon_without_passive_force_is_ignored_with_a_warning():
    """As in gymnasium's humanoid: fixed tendons that only couple joint ranges change no
    motion, so the model imports, saying what it left out."""
    xml = _xml(
        f"<body name='a'><freejoint/>{BODY}<body name='b'><joint name='j'/>{BODY}"
        f"<body name='c'><joint name='k'/>{BODY}</body></body></body>",
        "<tendon><fixed name='t' limited='true' range='-1 1'><joint joint='j' coef='1'/>"
        "<joint joint='k' coef='-1'/></fixed></tendon>",
    )
    with pytest.warns(UserWarning, match="tendon.*'t'.*no passive force"):
        assert multibody_from_mjcf(xml).shape_dim == 2


def test_clean_model_does_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        multibody_from_mjcf(MODELS / "tree4.xml")


def test_refs_warn(chain):
    with pytest.warns(UserWarning, match=r"'shoulder' \(ref 0.4\).*qpos0=model.qpos0"):
        multibody_from_mjcf(MODELS / "chain5.xml")
