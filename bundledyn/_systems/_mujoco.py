"""Import MJCF and URDF models through MuJoCo's own parser, and convert states both ways.

The importers read a compiled `mujoco.MjModel` (so every MJCF default, `childclass`,
`inertiafromgeom`, `fullinertia`, angle unit, `ref` … is resolved exactly as MuJoCo
resolves it) and build a `Multibody`:

- **The tree.** The worldbody must hold exactly one body, the *root*; it becomes the
  floating base (body 0) and its frame is the section frame. The root may carry a free
  joint or no joint at all; a root without one is still floated (bundledyn's systems
  move freely in space: MuJoCo welds such a root to the world, bundledyn does not — put a
  free joint on it to get the same state layout as MuJoCo). Links follow MuJoCo's body
  order, so $q$ and $\\dot q$ follow MuJoCo's joint order.
- **Joints** (axes and anchors in the child frame, MuJoCo's `jnt_axis` / `jnt_pos`):
  hinge → `Revolute`, slide → `Prismatic`, ball → `Spherical`; two hinges on one body whose
  axes intersect and are not parallel → `Universal` (anchored at the intersection); any
  other set of several joints on one body → `Composite`, in the body's joint order.
  `mj_kinematics` applies the joints of a body one after the other, each about its axis
  carried by the motion of the previous ones: pose $= P\\,J_1(q_1)J_2(q_2)\\cdots$ with $P$
  the body's `pos`/`quat` — exactly `Composite`'s order.
- **Bodies**: `body_mass`, `body_ipos` (centre of mass) and the inertia
  $R\\,\\operatorname{diag}(\\texttt{body\\_inertia})\\,R^T$, $R$ from `body_iquat`.
  A body with no mass and no joint (a frame for sites or cameras) is welded into its parent:
  it is not a bundledyn body, its children hang from the parent with the composed
  placement, and its name is absent from `Multibody.names`.
- **Joint offsets.** MuJoCo rotates a hinge by `qpos - qpos0` (and slides a slide by it),
  where `qpos0` is the joint's `ref`; the home placement (`body_pos`/`body_quat`) is the
  pose at `qpos = qpos0`. bundledyn's coordinate is therefore $q =$ `qpos - qpos0`, so
  $q = 0$ is the home pose; pass `qpos0=model.qpos0` to the converters when a model has
  non-zero refs (importing one warns).

Not supported (`ValueError` naming the element and the fix): several bodies under the
worldbody, a joint other than a free joint on the root, free joints below the root
(MuJoCo itself rejects those), equality constraints, tendons, bodies without mass that
carry joints, and a root body without mass.

Ignored, with one warning listing what the model had: contacts (geoms with a non-zero
`contype`/`conaffinity`), actuators, sensors, joint limits, joint stiffness, damping,
friction loss, armature (rotor inertia: MuJoCo adds it to its mass matrix, bundledyn's
metric does not have it), gravity compensation, fluid forces and flexes. Gravity
(`option/gravity`) is not imported either: it is an effect of the scene.

The state converters `state_from_mujoco` and `mujoco_from_state` are pure JAX (no
`mujoco` import; jit, vmap and grad work through them).
"""

import os
import warnings

import jax.numpy as jnp
import numpy as np

from .. import lie
from ._joints import Composite, Fixed, Prismatic, Revolute, Spherical, Universal
from ._multibody import Link, Multibody
from ._rigid_body import RigidBody

__all__ = [
    "multibody_from_mjcf",
    "multibody_from_urdf",
    "multibody_from_mjmodel",
    "state_from_mujoco",
    "mujoco_from_state",
]

# MuJoCo's mjtJoint values.
_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_JOINT_NAMES = {_FREE: "free", _BALL: "ball", _SLIDE: "slide", _HINGE: "hinge"}
_MINVAL = 1e-15  # mjMINVAL: MuJoCo's threshold for "no mass"


def _import_mujoco():
    try:
        import mujoco
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            "Importing MJCF/URDF models needs MuJoCo's parser: "
            'install it with `pip install "bundledyn[mujoco]"`.'
        ) from e
    return mujoco


# --------------------------------------------------------------------------------------
# Importers
# --------------------------------------------------------------------------------------


def multibody_from_mjcf(source, *, section=0) -> Multibody:
    """Build a `Multibody` from an MJCF model with MuJoCo's own parser.

    See the module docstring for what is imported, what is ignored (with a warning) and
    what is refused (with a `ValueError`).

    **Arguments:**

    - `source`: a path (`str` or `os.PathLike`) to an MJCF file, an MJCF XML string, or
      an already compiled `mujoco.MjModel`.
    - `section`: the body whose frame is the section frame, by index (0, the root, by
      default) or by MuJoCo body name. The converters handle any section.

    **Returns:**

    A `Multibody` whose base is the root body and whose links follow MuJoCo's body order
    (bodies with no mass and no joint are welded into their parents); `names` are the
    MuJoCo body names. Its state relates to MuJoCo's `qpos`/`qvel` through
    `state_from_mujoco` / `mujoco_from_state`.
    """
    mujoco = _import_mujoco()
    model = source if isinstance(source, mujoco.MjModel) else _compile(mujoco, source)
    return multibody_from_mjmodel(model, section=section)


def _compile(mujoco, source):
    if isinstance(source, os.PathLike) or (
        isinstance(source, str) and not source.lstrip().startswith("<")
    ):
        path = os.fspath(source)
        if not os.path.isfile(path):
            raise FileNotFoundError(
                f"no MJCF file at {path!r}; pass a path to an existing file or an XML string "
                "(starting with '<')."
            )
        loader, what = mujoco.MjModel.from_xml_path, f"the model file {path!r}"
        arg = path
    elif isinstance(source, str):
        loader, what, arg = mujoco.MjModel.from_xml_string, "the MJCF string", source
    else:
        raise ValueError(
            "`source` must be a path to an MJCF file, an MJCF XML string or a "
            f"mujoco.MjModel, got {type(source).__name__}."
        )
    try:
        return loader(arg)
    except ValueError as e:
        raise ValueError(f"MuJoCo could not compile {what}: {e}") from e


def multibody_from_urdf(path, *, section=0) -> Multibody:
    """Build a `Multibody` from a URDF file with MuJoCo's own URDF parser.

    The root link becomes the floating base: it is given a free joint before compiling
    (MuJoCo's URDF import would otherwise weld it to the world and, with `fusestatic`,
    fuse it into the worldbody), so `qpos`/`qvel` of the compiled model start with the
    free joint's 7/6 entries like an MJCF model with a free root. MuJoCo fuses links
    attached by `fixed` joints into their parents by default (`fusestatic`, the URDF
    default): they are not separate bodies, their inertia is added to the parent's.
    Joint `limit`s, `dynamics` and collision geometry are ignored (with a warning), as for
    MJCF.

    **Arguments:**

    - `path`: path to a `.urdf` file (meshes are resolved relative to it by MuJoCo).
    - `section`: the section body, by index or link name (see `multibody_from_mjcf`).

    **Returns:**

    A `Multibody` (see `multibody_from_mjcf`).
    """
    model = _compile_urdf(_import_mujoco(), path)
    return multibody_from_mjmodel(model, section=section)


def _compile_urdf(mujoco, path):
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no URDF file at {path!r}.")
    try:
        spec = mujoco.MjSpec.from_file(path)
        roots = list(spec.worldbody.bodies)
        if len(roots) == 1 and not list(roots[0].joints):
            roots[0].add_freejoint()
        return spec.compile()
    except ValueError as e:
        raise ValueError(f"MuJoCo could not compile the URDF file {path!r}: {e}") from e


def _quat_to_matrix(quat):
    """Rotation matrix of a (w, x, y, z) quaternion, in NumPy (normalized first)."""
    w, x, y, z = np.asarray(quat, dtype=float) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _pose_np(pos, quat):
    T = np.eye(4)
    T[:3, :3] = _quat_to_matrix(quat)
    T[:3, 3] = pos
    return T


def _name(model, kind, i):
    name = getattr(model, kind)(i).name
    return name if name else f"{kind}{i}"


def _joint_label(model, j):
    return f"'{_name(model, 'joint', j)}' ({_JOINT_NAMES[int(model.jnt_type[j])]})"


def _single_joint(model, j):
    jtype = int(model.jnt_type[j])
    axis = np.array(model.jnt_axis[j], dtype=float)
    anchor = np.array(model.jnt_pos[j], dtype=float)
    if jtype == _HINGE:
        return Revolute(axis, anchor)
    if jtype == _SLIDE:
        return Prismatic(axis)
    if jtype == _BALL:
        return Spherical(anchor)
    raise AssertionError(f"unexpected joint type {jtype}")  # free joints are refused earlier


def _universal_anchor(model, j1, j2):
    """The intersection of two hinge axes, or None when they are parallel or skew."""
    a1, a2 = np.array(model.jnt_axis[j1], float), np.array(model.jnt_axis[j2], float)
    a1, a2 = a1 / np.linalg.norm(a1), a2 / np.linalg.norm(a2)
    p1, p2 = np.array(model.jnt_pos[j1], float), np.array(model.jnt_pos[j2], float)
    n = np.cross(a1, a2)
    if np.linalg.norm(n) < 1e-8:
        return None
    scale = max(1.0, np.linalg.norm(p1), np.linalg.norm(p2))
    if abs(np.dot(p2 - p1, n)) / np.linalg.norm(n) > 1e-10 * scale:
        return None
    # p1 + t a1 = p2 + s a2 (consistent: the lines are coplanar and not parallel).
    (t, _), *_ = np.linalg.lstsq(np.stack([a1, -a2], axis=1), p2 - p1, rcond=None)
    return p1 + t * a1


def _body_joint(model, b, joints):
    if not joints:
        return Fixed()
    if len(joints) == 1:
        return _single_joint(model, joints[0])
    if len(joints) == 2 and all(int(model.jnt_type[j]) == _HINGE for j in joints):
        anchor = _universal_anchor(model, *joints)
        if anchor is not None:
            return Universal(model.jnt_axis[joints[0]], model.jnt_axis[joints[1]], anchor)
    return Composite([_single_joint(model, j) for j in joints])


def _check_unsupported(model):
    if model.neq > 0:
        names = ", ".join(f"'{_name(model, 'equality', i)}'" for i in range(model.neq))
        raise ValueError(
            f"the model has {model.neq} equality constraint(s) ({names}); bundledyn's "
            "Multibody is a tree without closed loops or welds. Remove the <equality> "
            "elements (model a weld by putting the bodies in one body, a loop by cutting it)."
        )
    if model.ntendon > 0:
        names = ", ".join(f"'{_name(model, 'tendon', i)}'" for i in range(model.ntendon))
        raise ValueError(
            f"the model has {model.ntendon} tendon(s) ({names}); tendons (their lengths, "
            "limits, springs and the actuators that drive them) are not supported. Remove "
            "the <tendon> elements and whatever refers to them."
        )
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if not roots:
        raise ValueError("the model has no body under the worldbody: nothing to import.")
    if len(roots) > 1:
        names = ", ".join(f"'{_name(model, 'body', b)}'" for b in roots)
        raise ValueError(
            f"the worldbody holds {len(roots)} bodies ({names}); bundledyn imports one "
            "floating tree whose root is the single body under the worldbody. Nest them "
            "under one root body, remove static scenery bodies (put their geoms directly in "
            "the worldbody), or import each tree as its own model."
        )
    root = roots[0]
    for j in range(model.njnt):
        b = int(model.jnt_bodyid[j])
        if int(model.jnt_type[j]) == _FREE and b != root:
            raise ValueError(
                f"free joint {_joint_label(model, j)} on body '{_name(model, 'body', b)}' "
                "below the root: only the root body may float freely. Remove the free joint "
                "or attach the body by other joints."
            )
    root_joints = [int(model.body_jntadr[root]) + k for k in range(model.body_jntnum[root])]
    if root_joints and not (len(root_joints) == 1 and int(model.jnt_type[root_joints[0]]) == _FREE):
        labels = ", ".join(_joint_label(model, j) for j in root_joints)
        raise ValueError(
            f"the root body '{_name(model, 'body', root)}' is attached to the world by "
            f"{labels}; bundledyn floats the root body, so these joints would be lost. "
            "Give the root a free joint (or no joint), or add a root body with mass and no "
            "joint and hang this body from it by these joints."
        )
    return root


def _ignored_elements(model):
    ignored = []
    contact = np.flatnonzero((model.geom_contype != 0) | (model.geom_conaffinity != 0))
    if contact.size:
        ignored.append(f"contacts of {contact.size} collision geom(s)")
    if model.nu:
        ignored.append(f"{model.nu} actuator(s)")
    if model.nsensor:
        ignored.append(f"{model.nsensor} sensor(s)")

    def joints_where(mask, what):
        js = sorted({int(j) for j in np.flatnonzero(mask)})
        if js:
            names = ", ".join(f"'{_name(model, 'joint', j)}'" for j in js)
            ignored.append(f"{what} of joint(s) {names}")

    joints_where(np.asarray(model.jnt_limited, bool), "limits")
    joints_where(np.asarray(model.jnt_stiffness) != 0, "stiffness")
    dof_joint = np.asarray(model.dof_jntid)
    for field, what in (
        ("dof_damping", "damping"),
        ("dof_frictionloss", "friction loss"),
        ("dof_armature", "armature (rotor inertia, part of MuJoCo's mass matrix)"),
    ):
        mask = np.zeros(model.njnt, bool)
        mask[dof_joint[np.asarray(getattr(model, field)) != 0]] = True
        joints_where(mask, what)
    if np.any(np.asarray(model.body_gravcomp) != 0):
        ignored.append("gravity compensation (body gravcomp)")
    if model.opt.density != 0 or model.opt.viscosity != 0:
        ignored.append("fluid forces (option density/viscosity)")
    if model.nflex:
        ignored.append(f"{model.nflex} flex(es)")
    return ignored


def multibody_from_mjmodel(model, *, section=0) -> Multibody:
    """Build a `Multibody` from a compiled `mujoco.MjModel` (see `multibody_from_mjcf`)."""
    root = _check_unsupported(model)

    def rigid_body(b):
        name = _name(model, "body", b)
        R = _quat_to_matrix(model.body_iquat[b])
        inertia = R @ np.diag(model.body_inertia[b]) @ R.T
        try:
            return RigidBody(float(model.body_mass[b]), np.array(model.body_ipos[b]), inertia)
        except ValueError as e:
            raise ValueError(f"body '{name}': {e}") from e

    if model.body_mass[root] < _MINVAL:
        raise ValueError(
            f"the root body '{_name(model, 'body', root)}' has no mass; it becomes bundledyn's "
            "floating base, which must be a rigid body with mass. Give it an <inertial> "
            "(or geoms with mass), or remove it so that its child is the root."
        )
    base = rigid_body(root)
    names = [_name(model, "body", root)]
    index = {root: 0}  # MuJoCo body -> bundledyn body
    welded = {}  # MuJoCo body welded away -> (bundledyn body, its pose in that body)
    links = []
    refs = []
    for b in range(root + 1, model.nbody):
        p = int(model.body_parentid[b])
        local = _pose_np(model.body_pos[b], model.body_quat[b])
        if p in index:
            parent, placement = index[p], local
        else:
            parent, offset = welded[p]
            placement = offset @ local
        joints = [int(model.body_jntadr[b]) + k for k in range(model.body_jntnum[b])]
        if model.body_mass[b] < _MINVAL:
            name = _name(model, "body", b)
            if joints:
                labels = ", ".join(_joint_label(model, j) for j in joints)
                raise ValueError(
                    f"body '{name}' carries joint(s) {labels} but has no mass: every "
                    "bundledyn body is a rigid body with positive mass and inertia (MuJoCo "
                    "accepts a massless moving body when a welded child carries mass). Give "
                    f"'{name}' an <inertial>, or move its joints into its child body (several "
                    "joints on one body are supported and act in order)."
                )
            welded[b] = (parent, placement)
            continue
        for j in joints:
            if int(model.jnt_type[j]) in (_HINGE, _SLIDE):
                ref = float(model.qpos0[model.jnt_qposadr[j]])
                if ref != 0.0:
                    refs.append(f"'{_name(model, 'joint', j)}' (ref {ref:g})")
        index[b] = len(links) + 1
        names.append(_name(model, "body", b))
        links.append(Link(rigid_body(b), _body_joint(model, b, joints), parent, placement))
    if isinstance(section, str):
        if section not in names:
            raise ValueError(
                f"`section` names body {section!r}, which is not a body of the imported tree; "
                f"its bodies are {names}."
            )
        section = names.index(section)
    system = Multibody(base, links, section=section, names=names)
    ignored = _ignored_elements(model)
    if ignored:
        warnings.warn(
            "bundledyn's Multibody keeps the kinematic tree and the inertias only; ignored "
            "from the MuJoCo model: " + "; ".join(ignored) + ".",
            stacklevel=3,
        )
    if refs:
        warnings.warn(
            "joint(s) " + ", ".join(refs) + " have a non-zero reference position: bundledyn's "
            "coordinate is q = qpos - qpos0, zero at the home pose. Pass qpos0=model.qpos0 to "
            "state_from_mujoco / mujoco_from_state.",
            stacklevel=3,
        )
    return system


# --------------------------------------------------------------------------------------
# State converters (pure JAX)
# --------------------------------------------------------------------------------------


def _layout(system, free_root):
    """Static index tables between bundledyn's q and MuJoCo's qpos/qvel.

    Screw nodes (hinge/slide) take 1 qpos and 1 qvel entry, ball nodes 4 qpos (a
    quaternion) and 3 qvel entries, in node order, which is the order of q.
    """
    t = system._tables
    pos, vel = (7, 6) if free_root else (0, 0)
    screw_q, screw_pos, screw_vel, ball_q, ball_pos, ball_vel = [], [], [], [], [], []
    last = -1
    for kind, start in zip(t.kinds, t.q_start, strict=True):
        if kind == "screw":
            screw_q.append(start), screw_pos.append(pos), screw_vel.append(vel)
            pos, vel = pos + 1, vel + 1
        elif kind == "ball":
            ball_q.append(start + np.arange(3))
            ball_pos.append(pos + np.arange(4))
            ball_vel.append(vel + np.arange(3))
            pos, vel = pos + 4, vel + 3
        else:
            continue
        if start < last:  # pragma: no cover - Multibody numbers q in node order
            raise AssertionError("shape coordinates are not in node order")
        last = start
    as_int = lambda x, shape: np.asarray(x, dtype=int).reshape(shape)
    return dict(
        screw_q=as_int(screw_q, (-1,)),
        screw_pos=as_int(screw_pos, (-1,)),
        screw_vel=as_int(screw_vel, (-1,)),
        ball_q=as_int(ball_q, (-1, 3)),
        ball_pos=as_int(ball_pos, (-1, 4)),
        ball_vel=as_int(ball_vel, (-1, 3)),
        nq=pos,
        nv=vel,
    )


def _check_length(name, x, n, free_root):
    if x.shape != (n,):
        free = " (7 free-joint entries first)" if free_root else " (no free-joint part)"
        raise ValueError(
            f"`{name}` must have shape ({n},){free} for this system with "
            f"free_root={free_root}, got {x.shape}; use jax.vmap for batches."
        )


def _screw_offsets(qpos0, lay, free_root, dtype):
    if qpos0 is None:
        return jnp.zeros(lay["screw_pos"].shape, dtype)
    qpos0 = jnp.asarray(qpos0, dtype)
    _check_length("qpos0", qpos0, lay["nq"], free_root)
    return qpos0[lay["screw_pos"]]


_ATAN_SERIES = tuple(1.0 / (2 * k + 1) for k in range(12))  # atan(t)/t in -t²


def _rotation_vector_from_quaternion(quat):
    """The rotation vector $\\varphi$, $|\\varphi| \\le \\pi$, of a quaternion (unit or not).

    $\\varphi = 2\\operatorname{atan2}(|u|, w)\\,u/|u|$ after flipping the sign so that
    $w \\ge 0$ — the same as `so3_log(rotation_from_quaternion(quat))`, without the matrix.
    Near the identity ($|u|^2 < 10^{-2} w^2$) the factor $\\arctan(|u|/w)/|u|$ is its
    series in $|u|^2/w^2$, so values and derivatives are exact at $\\varphi = 0$.
    """
    quat = jnp.where(quat[..., :1] < 0, -quat, quat)
    w, u = quat[..., 0], quat[..., 1:]
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


def _quaternion_from_rotation_vector(phi):
    """(cos θ/2, sin(θ/2) φ/θ), θ = |φ|, with a Taylor branch at θ = 0 (safe gradients)."""
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


def _section_root(system, q):
    """Root pose $r_0$ in the section frame and the q̇-columns of its section-frame velocity."""
    r, Jhat = system.velocity_jacobians(q)
    return r[0], Jhat[0, :, 6:]


def state_from_mujoco(system, qpos, qvel, *, qpos0=None, free_root=True, root_pose=None):
    """bundledyn's state $(g, q, \\xi, \\dot q)$ from MuJoCo's `qpos`, `qvel`.

    Conventions (DESIGN §2): $g$ is the pose of the section frame (the root body's frame
    for an imported model), $\\xi = g^{-1}\\dot g = (\\omega, v)$ its body velocity. The free
    joint's `qpos` is (position, quaternion $w$ first) and its `qvel` is (linear velocity
    of the body origin in **world** axes, angular velocity in **body** axes), so
    $\\xi = (\\omega_{body}, R^T v_{world})$. The remaining coordinates follow MuJoCo's joint
    order: a hinge or slide has $q =$ `qpos - qpos0` and $\\dot q =$ `qvel`; a ball joint
    has the rotation vector $\\varphi$ of its quaternion ($\\exp\\tilde\\varphi = R(\\text{quat})$,
    $|\\varphi| \\le \\pi$) and
    $\\dot\\varphi = \\operatorname{dexp}^{-1}(\\varphi)\\,\\omega$, $\\omega$ its `qvel` (the
    child's angular velocity relative to its parent, in the child's axes).

    Pure JAX: jit, grad and vmap (over a batch of states) work through it.

    **Arguments:**

    - `system`: a `Multibody` (e.g. from `multibody_from_mjcf`); any section body.
    - `qpos`, `qvel`: MuJoCo's generalized positions and velocities, shapes `(nq,)`, `(nv,)`.
    - `qpos0`: MuJoCo's `model.qpos0` (same layout as `qpos`), for joints with a non-zero
      `ref`; default: no offsets.
    - `free_root`: whether `qpos`/`qvel` start with the root's free joint (7/6 entries).
      For a root without a free joint, MuJoCo welds it to the world: then $g$ is
      `root_pose` and the root's body velocity is zero.
    - `root_pose`: the root's 4×4 pose when `free_root=False` (MuJoCo's `xpos`/`xmat` of
      the root body); default identity.

    **Returns:**

    `(g, q, xi, qdot)` with shapes `(4, 4)`, `(d,)`, `(6,)`, `(d,)`.
    """
    qpos = jnp.asarray(qpos)
    qvel = jnp.asarray(qvel)
    dtype = jnp.result_type(qpos.dtype, qvel.dtype, float)
    qpos, qvel = qpos.astype(dtype), qvel.astype(dtype)
    lay = _layout(system, free_root)
    _check_length("qpos", qpos, lay["nq"], free_root)
    _check_length("qvel", qvel, lay["nv"], free_root)

    if free_root:
        R = lie.rotation_from_quaternion(qpos[3:7])
        g_root = lie.se3_from_rotation_translation(R, qpos[0:3])
        nu_root = jnp.concatenate([qvel[3:6], R.T @ qvel[0:3]])
    else:
        g_root = jnp.eye(4, dtype=dtype) if root_pose is None else jnp.asarray(root_pose, dtype)
        nu_root = jnp.zeros(6, dtype)

    offsets = _screw_offsets(qpos0, lay, free_root, dtype)
    phi = _rotation_vector_from_quaternion(qpos[lay["ball_pos"]])
    phidot = jnp.einsum("kij,kj->ki", lie.so3_dexp_inv(phi), qvel[lay["ball_vel"]])
    d = system.shape_dim
    q = jnp.zeros(d, dtype).at[lay["screw_q"]].set(qpos[lay["screw_pos"]] - offsets)
    q = q.at[lay["ball_q"]].set(phi)
    qdot = jnp.zeros(d, dtype).at[lay["screw_q"]].set(qvel[lay["screw_vel"]])
    qdot = qdot.at[lay["ball_q"]].set(phidot)

    if system.section == 0:
        return g_root, q, nu_root, qdot
    # s_0 = g r_0(q): g = g_0 r_0⁻¹, and ν_0 = Ad_{r_0⁻¹}(ξ + Z_0 q̇).
    r0, Z0 = _section_root(system, q)
    g = g_root @ lie.se3_inv(r0)
    xi = lie.Ad(r0) @ nu_root - Z0 @ qdot
    return g, q, xi, qdot


def mujoco_from_state(system, g, q, xi, qdot, *, qpos0=None, free_root=True):
    """MuJoCo's `qpos`, `qvel` from bundledyn's state $(g, q, \\xi, \\dot q)$.

    The inverse of `state_from_mujoco` (same conventions): the free joint gets the root's
    position and unit quaternion ($w \\ge 0$) and (world linear, body angular) velocity; a
    hinge or slide gets `qpos = q + qpos0`; a ball joint the unit quaternion of
    $\\exp(\\tilde\\varphi)$ and `qvel` $= \\operatorname{dexp}(\\varphi)\\dot\\varphi$.
    Pure JAX (jit/grad/vmap).

    **Arguments:**

    - `system`: the `Multibody`.
    - `g`, `q`, `xi`, `qdot`: the state, shapes `(4, 4)`, `(d,)`, `(6,)`, `(d,)`.
    - `qpos0`: MuJoCo's `model.qpos0` (same layout as `qpos`), for joints with a non-zero
      `ref`; default: no offsets.
    - `free_root`: whether to write the root's free joint (7/6 entries) first. With
      `free_root=False` the pose and velocity of the root are dropped (MuJoCo welds a root
      without a free joint to the world).

    **Returns:**

    `(qpos, qvel)`, shapes `(nq,)`, `(nv,)`.
    """
    dtype = jnp.result_type(
        jnp.asarray(g).dtype, jnp.asarray(q).dtype, jnp.asarray(xi).dtype, float
    )
    g, q, xi, qdot = (jnp.asarray(x, dtype) for x in (g, q, xi, qdot))
    d = system.shape_dim
    for name, x, shape in (
        ("g", g, (4, 4)),
        ("q", q, (d,)),
        ("xi", xi, (6,)),
        ("qdot", qdot, (d,)),
    ):
        if x.shape != shape:
            raise ValueError(
                f"`{name}` must have shape {shape}, got {x.shape}; use jax.vmap for batches."
            )
    lay = _layout(system, free_root)

    qpos = jnp.zeros(lay["nq"], dtype)
    qvel = jnp.zeros(lay["nv"], dtype)
    if free_root:
        if system.section == 0:
            g_root, nu_root = g, xi
        else:
            r0, Z0 = _section_root(system, q)
            g_root = g @ r0
            nu_root = lie.Ad(lie.se3_inv(r0)) @ (xi + Z0 @ qdot)
        R = g_root[:3, :3]
        qpos = qpos.at[0:3].set(g_root[:3, 3]).at[3:7].set(lie.quaternion_from_rotation(R))
        qvel = qvel.at[0:3].set(R @ nu_root[3:6]).at[3:6].set(nu_root[0:3])

    offsets = _screw_offsets(qpos0, lay, free_root, dtype)
    qpos = qpos.at[lay["screw_pos"]].set(q[lay["screw_q"]] + offsets)
    qvel = qvel.at[lay["screw_vel"]].set(qdot[lay["screw_q"]])
    phi = q[lay["ball_q"]]
    omega = jnp.einsum("kij,kj->ki", lie.so3_dexp(phi), qdot[lay["ball_q"]])
    qpos = qpos.at[lay["ball_pos"]].set(_quaternion_from_rotation_vector(phi))
    qvel = qvel.at[lay["ball_vel"]].set(omega)
    return qpos, qvel
