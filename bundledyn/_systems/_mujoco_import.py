r"""Import MJCF and URDF models through MuJoCo's own parser, and convert states both ways.

The importers read a compiled `mujoco.MjModel` (so every MJCF default, `childclass`,
`inertiafromgeom`, `fullinertia`, angle unit, `ref` … is resolved exactly as MuJoCo
resolves it) and build a `Multibody`:

- **The tree.** The *root* is the body under the worldbody. A root with a free
  joint becomes the base (body 0) and its frame the section frame. MuJoCo welds a root
  without a joint to the world, and so does `Scene.from_mjcf` (and a scene file or
  `bundledyn.load_scene` of the model): the root is the base, held at its pose
  (`PrescribedBase.fixed`, `ModelParts.root_pose`); the tree alone (`Multibody.from_mjcf`)
  is a system any scene may float. Put a `<freejoint/>` on the root to float it in MuJoCo
  and in bundledyn alike. A root attached to the world by hinges, slides or a ball joint
  (a pendulum, a cart-pole, a planar walker's root slides and hinge) hangs from the world:
  the base is a stand-in for the world (body `world`, unit mass and inertia at the origin,
  `world_stand_in`) that `Scene.from_mjcf` holds fixed at the world's frame, so its inertia
  enters no equation, and the root's joints are the first shape coordinates, as in
  MuJoCo's `qpos`. Links follow MuJoCo's body order, so $q$ and $\dot q$ follow MuJoCo's
  joint order. Several bodies under the worldbody (a finger and its spinner, a cup and its
  ball, an arm and the object it pushes) are several trees hanging from the same held
  world, each attached by joints, welded or free; a body welded to the world never moves
  and is not a bundledyn body. The free joint of such a tree (dm_control's dog and its
  ball) is three slides along the world's axes and a ball joint at the body's origin: six
  shape coordinates for `qpos`'s seven entries, with MuJoCo's velocities (linear in the
  world's axes, angular in the body's).
- **Joints** (axes and anchors in the child frame, MuJoCo's `jnt_axis` / `jnt_pos`):
  hinge → `Revolute`, slide → `Prismatic`, ball → `Spherical`; two hinges on one body whose
  axes intersect and are not parallel → `Universal` (anchored at the intersection); any
  other set of several joints on one body → `Composite`, in the body's joint order.
  `mj_kinematics` applies the joints of a body one after the other, each about its axis
  carried by the motion of the previous ones: pose $= P\,J_1(q_1)J_2(q_2)\cdots$ with $P$
  the body's `pos`/`quat` — exactly `Composite`'s order.
- **Bodies**: `body_mass`, `body_ipos` (centre of mass) and the inertia
  $R\,\operatorname{diag}(\texttt{body\_inertia})\,R^T$, $R$ from `body_iquat`.
  A body with no mass and no joint (a frame for sites or cameras) is welded into its parent:
  it is not a bundledyn body, its children hang from the parent with the composed
  placement, and its name is absent from `Multibody.names`.
- **Joint offsets.** MuJoCo rotates a hinge by `qpos - qpos0` (and slides a slide by it),
  where `qpos0` is the joint's `ref`; the home placement (`body_pos`/`body_quat`) is the
  pose at `qpos = qpos0`. bundledyn's coordinate is therefore $q =$ `qpos - qpos0`, so
  $q = 0$ is the home pose; pass `qpos0=model.qpos0` to the converters when a model has
  non-zero refs (importing one warns).

Not supported (`ValueError` naming the element and the fix): free joints below a root
(MuJoCo itself rejects those), equality constraints other than joint couplings, spatial
tendons, the armature of
tendons, bodies without mass that carry joints, and a root body without mass; when the
passive forces are asked for, also nonlinear or plastic springs and dampers (MuJoCo's
polynomial `stiffness`/`damping` terms, `springyield`) and tendon springs with a dead
band (two `springlength` values).

Kept: the armature (rotor inertia) of hinges and slides, which MuJoCo adds to its mass
matrix, as the `Multibody`'s `armature`; when asked (`passive=True`), the linear passive
forces: the hinges' and slides' `damping`, their `stiffness` about `springref`, and the
`stiffness` and `damping` of fixed tendons, whose length $L = \sum_k c_k\,$`qpos`$_k$
is a linear function of the shape coordinates (`FixedTendon`).

Ignored, with one warning listing what the model had: contacts (geoms with a non-zero
`contype`/`conaffinity`), actuators, sensors, joint and tendon limits, fixed tendons
without a spring or damper, joint and tendon friction loss, the armature, damping and
stiffness of ball and free joints, gravity compensation, fluid forces and flexes; and,
unless asked for, the passive forces. Gravity (`option/gravity`) is an effect of the scene (`Scene.from_mjcf`).

The state converters are in `_mujoco_state.py`.
"""

import os
import warnings
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np

from .. import lie
from ._joints import Composite, Fixed, Prismatic, Revolute, Spherical, Universal
from ._link import Link
from ._rigid_body import RigidBody

__all__ = [
    "WORLD",
    "FixedTendon",
    "SpatialTendon",
    "ModelParts",
    "compiled_mjcf",
    "parts_from_mjcf",
    "parts_from_mjmodel",
    "parts_from_urdf",
    "world_stand_in",
    "model_turns_off",
]

# MuJoCo's mjtJoint values.
_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_EQ_JOINT = 2  # mujoco.mjtEq.mjEQ_JOINT: a joint's position a polynomial of another's
_WRAP_JOINT = 1  # mjtWrap.mjWRAP_JOINT: a fixed tendon's joint term
_WRAP_SITE = 3  # mjtWrap.mjWRAP_SITE: a spatial tendon's site
_JOINT_NAMES = {_FREE: "free", _BALL: "ball", _SLIDE: "slide", _HINGE: "hinge"}
_MINVAL = 1e-15  # mjMINVAL: MuJoCo's threshold for "no mass"
_DISABLE_GRAVITY = 1 << 7  # mjtDisableBit.mjDSBL_GRAVITY: `<flag gravity="disable">`
_DISABLE_SPRING = 1 << 5  # mjtDisableBit.mjDSBL_SPRING: `<flag spring="disable">`
_DISABLE_DAMPER = 1 << 6  # mjtDisableBit.mjDSBL_DAMPER: `<flag damper="disable">`


class FixedTendon(NamedTuple):
    r"""A fixed tendon with a spring or a damper: its length is linear in the shape,
    $L(q) = c^T q + L_0$, and MuJoCo's passive force $-k\,(L - L_s) - b\,\dot L$ acts
    along it, i.e. the generalized force $-c\,(k\,(L - L_s) + b\,c^T\dot q)$.

    **Fields:** `name`, `coefficients` ($c$, one per shape coordinate: MuJoCo's `coef`
    of each joint, zero elsewhere), `length_at_home` ($L_0$, the length at $q = 0$,
    i.e. at `qpos0`), `stiffness` ($k$), `damping` ($b$) and `spring_length` ($L_s$).
    """

    name: str
    coefficients: np.ndarray
    length_at_home: float
    stiffness: float
    damping: float
    spring_length: float


class SpatialTendon(NamedTuple):
    r"""A spatial tendon from site to site with a spring or a damper: MuJoCo's passive
    force $-k\,(L - L_s) - b\,\dot L$ along it (`TendonSpring`, `TendonDamper`).

    **Fields:** `name`, `bodies` (each site's bundledyn body, along the tendon), `points`
    (each site in its body's frame, `(n, 3)`: a `SitePath`'s), `stiffness` ($k$),
    `damping` ($b$), `spring_length` ($L_s$).
    """

    name: str
    bodies: tuple[int, ...]
    points: np.ndarray
    stiffness: float
    damping: float
    spring_length: float


class ModelParts(NamedTuple):
    r"""What an imported model's tree is made of, ready for `Multibody`.

    **Fields:** `base` (the root `RigidBody`), `links` (the `Link`s in MuJoCo's body
    order), `names` (the bodies' MuJoCo names, base first), `model` (the compiled
    `mujoco.MjModel` they were read from), per shape coordinate the hinges' and slides'
    `armature` (rotor inertia), `damping`, `stiffness` and `spring_rest` (`springref` as a
    shape coordinate, $q = $ `qpos - qpos0`), zero for a ball joint's coordinates, the
    fixed `tendons` with a spring or a damper (`FixedTendon`), the `spatial_tendons`
    with one (`SpatialTendon`, read when the passive forces are asked for), `ignored` (what the import
    left out, as the warning lists it), the active joint equalities as `couplings`
    `(dependent, independent, polycoef)` of shape coordinates (`JointCoupling`'s; with
    $q = $ `qpos - qpos0` MuJoCo's $y - y_0 = \sum_k a_k (x - x_0)^k$ reads
    $q_y = \sum_k a_k q_x^k$; `independent` None where the joint is held), and the
    `root_pose` `(4, 4)` where the base is held: the root's pose where MuJoCo welds the
    root to the world (a root without a joint), the identity where the root hangs from
    the world by joints (the base is then `world_stand_in()`), None for a free root.
    """

    base: RigidBody
    links: tuple[Link, ...]
    names: tuple[str, ...]
    model: Any
    armature: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    spring_rest: np.ndarray
    tendons: tuple[FixedTendon, ...]
    ignored: tuple[str, ...]
    couplings: tuple[tuple[int, int | None, np.ndarray], ...] = ()
    root_pose: np.ndarray | None = None
    spatial_tendons: tuple[SpatialTendon, ...] = ()


def _import_mujoco():
    try:
        import mujoco
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            "Importing MJCF/URDF models needs MuJoCo's parser: "
            'install it with `pip install "bundledyn[mujoco]"`.'
        ) from e
    return mujoco


def model_gravity(model) -> np.ndarray | None:
    """The acceleration of gravity a compiled model states (`<option gravity>`), or None
    where its `<flag gravity="disable">` turns gravity off."""
    if model.opt.disableflags & _DISABLE_GRAVITY:
        return None
    return np.asarray(model.opt.gravity, dtype=float)


def model_turns_off(model) -> tuple[str, ...]:
    """The passive forces a compiled model's `<flag>`s turn off: `"spring"` where
    `<flag spring="disable">`, `"damper"` where `<flag damper="disable">`."""
    flags = int(model.opt.disableflags)
    return tuple(
        name
        for name, bit in (("spring", _DISABLE_SPRING), ("damper", _DISABLE_DAMPER))
        if flags & bit
    )


# --------------------------------------------------------------------------------------
# Importers
# --------------------------------------------------------------------------------------


def parts_from_mjcf(source, *, passive: bool = False) -> ModelParts:
    """The parts of the tree of an MJCF model, compiled by MuJoCo's own parser.

    **Arguments:**

    - `source`: a path (`str` or `os.PathLike`) to an MJCF file, an MJCF XML string, or
      an already compiled `mujoco.MjModel`.
    - `passive`: whether the joints' springs and dampers will be used (not warned about).

    **Returns:**

    The `ModelParts`.
    """
    return parts_from_mjmodel(compiled_mjcf(source), passive=passive)


def compiled_mjcf(source):
    """The `mujoco.MjModel` of `source`: a path to an MJCF file, an MJCF XML string, or an
    already compiled `mujoco.MjModel` (given back as it is)."""
    mujoco = _import_mujoco()
    # MuJoCo's bindings are compiled and ship no type stubs: pyright cannot see `MjModel`.
    is_model = isinstance(source, mujoco.MjModel)  # pyright: ignore[reportAttributeAccessIssue]
    return source if is_model else _compile(mujoco, source)


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


def parts_from_urdf(path, *, passive: bool = False) -> ModelParts:
    """The parts of the tree of a URDF model, compiled by MuJoCo's own URDF parser.

    The root link becomes the floating base: it is given a free joint before compiling
    (MuJoCo's URDF import would otherwise weld it to the world and, with `fusestatic`,
    fuse it into the worldbody), so `qpos`/`qvel` of the compiled model start with the
    free joint's 7/6 entries like an MJCF model with a free root. MuJoCo fuses links
    attached by `fixed` joints into their parents by default (`fusestatic`, the URDF
    default): they are not separate bodies, their inertia is added to the parent's.
    Joint `limit`s and collision geometry are ignored (with a warning), as for MJCF; a
    joint's `<dynamics damping>` is MuJoCo's joint damping (kept with `passive`), its
    `friction` MuJoCo's friction loss (ignored).

    **Arguments:**

    - `path`: path to a `.urdf` file (meshes are resolved relative to it by MuJoCo).
    - `passive`: whether the joints' dampers will be used (not warned about).

    **Returns:**

    The `ModelParts`.
    """
    return parts_from_mjmodel(_compile_urdf(_import_mujoco(), path), passive=passive)


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


# The base of a model whose root is attached to the world by joints: MuJoCo's name of the
# world body, which no other body may take.
WORLD = "world"


def world_stand_in() -> RigidBody:
    """The world, as the base of a model whose root hangs from it by joints: a unit body
    at the world's origin. The scene holds it fixed, so its inertia enters no equation."""
    return RigidBody(1.0, np.zeros(3), np.eye(3))


def _quat_to_matrix(quat):
    """Rotation matrix of a (w, x, y, z) quaternion, as NumPy (`lie.rotation_from_quaternion`)."""
    return np.asarray(lie.rotation_from_quaternion(jnp.asarray(quat, dtype=float)))


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
    # A free joint of one of several trees, on the held world: MuJoCo's free joint moves
    # the body to its qpos position, then turns it by its quaternion, both in the world's
    # axes, with the linear velocity in the world's axes and the angular in the body's:
    # three slides along the world's axes, then a ball joint at the body's origin.
    return Composite([*(Prismatic(e) for e in np.eye(3)), Spherical(np.zeros(3))])


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


def _check_unsupported(model, passive: bool):
    others = [i for i in range(model.neq) if int(model.eq_type[i]) != _EQ_JOINT]
    if others:
        names = ", ".join(f"'{_name(model, 'equality', i)}'" for i in others)
        raise ValueError(
            f"the model has {len(others)} equality constraint(s) other than joint couplings "
            f"({names}); bundledyn's Multibody is a tree without closed loops or welds. Remove "
            "those <equality> elements (model a weld by putting the bodies in one body, a loop "
            "by cutting it)."
        )
    wrapped = [
        i for i in range(model.ntendon)
        if not _fixed_tendon(model, i) and not _site_tendon(model, i)
        and _tendon_is_passive(model, i)
    ]  # fmt: skip
    if wrapped and passive:
        raise ValueError(
            f"spatial tendon(s) {_names(model, 'tendon', wrapped)} with a spring or a damper "
            "wrap around geoms or pulleys; bundledyn's spatial tendons run straight between "
            "sites. Take the wrapping geoms and pulleys out of the tendon, or its stiffness "
            "and damping, or import without the passive forces."
        )
    rotors = np.flatnonzero(np.asarray(model.tendon_armature))
    if rotors.size:
        raise ValueError(
            f"tendon(s) {_names(model, 'tendon', rotors)} have an armature (inertia along the "
            "tendon); bundledyn's rotor inertia is per joint coordinate. Set the tendons' "
            "armature to 0, or put it on their joints if it belongs to them."
        )
    if passive:
        _check_linear_passive_forces(model)
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if not roots:
        raise ValueError("the model has no body under the worldbody: nothing to import.")
    for j in range(model.njnt):
        b = int(model.jnt_bodyid[j])
        if int(model.jnt_type[j]) == _FREE and b not in roots:
            raise ValueError(
                f"free joint {_joint_label(model, j)} on body '{_name(model, 'body', b)}' "
                "below the root: only the root body may float freely. Remove the free joint "
                "or attach the body by other joints."
            )
    return roots


def _free_root(model, b: int) -> bool:
    return bool(model.body_jntnum[b]) and int(model.jnt_type[model.body_jntadr[b]]) == _FREE


def _names(model, kind, indices):
    return ", ".join(f"'{_name(model, kind, int(i))}'" for i in indices)


def _wraps(model, i):
    return range(int(model.tendon_adr[i]), int(model.tendon_adr[i]) + int(model.tendon_num[i]))


def _fixed_tendon(model, i) -> bool:
    """Whether tendon `i` is fixed: its length a linear combination of joint coordinates."""
    return all(int(model.wrap_type[w]) == _WRAP_JOINT for w in _wraps(model, i))


def _site_tendon(model, i) -> bool:
    """Whether tendon `i` runs straight from site to site (no geom wrapping, no pulley)."""
    return all(int(model.wrap_type[w]) == _WRAP_SITE for w in _wraps(model, i))


def _tendon_is_passive(model, i) -> bool:
    return model.tendon_stiffness[i] != 0 or model.tendon_damping[i] != 0


def _check_linear_passive_forces(model):
    """Refuse the passive forces that a `ShapeSpring`/`ShapeDamper` would get wrong."""

    def rows(field):
        return np.any(np.atleast_2d(np.asarray(getattr(model, field))) != 0, axis=1)

    dof_joint = np.asarray(model.dof_jntid)
    joints = rows("jnt_stiffnesspoly") | (np.asarray(model.jnt_springyield) != 0)
    joints[dof_joint[rows("dof_dampingpoly")]] = True
    spring = np.asarray(model.tendon_lengthspring).reshape(-1, 2)
    dead_band = (np.asarray(model.tendon_stiffness) != 0) & (spring[:, 0] != spring[:, 1])
    tendons = rows("tendon_stiffnesspoly") | rows("tendon_dampingpoly") | dead_band
    tendons |= np.asarray(model.tendon_springyield) != 0
    offenders = [
        f"{kind}(s) {_names(model, kind, np.flatnonzero(mask))}"
        for kind, mask in (("joint", joints), ("tendon", tendons))
        if mask.any()
    ]
    if offenders:
        raise ValueError(
            " and ".join(offenders) + " have nonlinear or plastic passive forces (MuJoCo's "
            "polynomial `stiffness`/`damping` terms, `springyield`, or a tendon spring with "
            "a dead band, two `springlength` values); bundledyn maps linear springs and "
            "dampers. Remove those terms, or import without `passive=True` and add them to "
            "the scene as a `ShapePotential` or `ShapeForce`."
        )


def _fixed_tendons(model, coordinate: dict[int, int], d: int) -> tuple[FixedTendon, ...]:
    """The fixed tendons with a spring or a damper, on the shape coordinates `coordinate[j]`
    of the model's hinges and slides ($q = $ `qpos - qpos0`)."""
    tendons = []
    for i in range(model.ntendon):
        if not (_fixed_tendon(model, i) and _tendon_is_passive(model, i)):
            continue
        coefficients, length_at_home = np.zeros(d), 0.0
        for w in _wraps(model, i):
            j, coef = int(model.wrap_objid[w]), float(model.wrap_prm[w])
            coefficients[coordinate[j]] += coef
            length_at_home += coef * float(model.qpos0[model.jnt_qposadr[j]])
        tendons.append(
            FixedTendon(
                _name(model, "tendon", i),
                coefficients,
                length_at_home,
                float(model.tendon_stiffness[i]),
                float(model.tendon_damping[i]),
                float(np.ravel(model.tendon_lengthspring[i])[0]),
            )  # fmt: skip
        )
    return tuple(tendons)


def _ignored_elements(model, passive: bool):
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
    passive_tendons = [_tendon_is_passive(model, i) for i in range(model.ntendon)]
    plain = [i for i, kept in enumerate(passive_tendons) if not kept]
    if plain:
        ignored.append(
            f"tendon(s) {_names(model, 'tendon', plain)} (no passive force: their limits only)"
        )
    unused = [i for i, kept in enumerate(passive_tendons) if kept and not passive]
    if unused:
        ignored.append(f"springs and dampers of tendon(s) {_names(model, 'tendon', unused)}")
    friction = np.flatnonzero(np.asarray(model.tendon_frictionloss))
    if friction.size:
        ignored.append(f"friction loss of tendon(s) {_names(model, 'tendon', friction)}")
    dof_joint = np.asarray(model.dof_jntid)
    screw = np.isin(np.asarray(model.jnt_type), (_HINGE, _SLIDE))

    def dofs_where(field):
        mask = np.zeros(model.njnt, bool)
        mask[dof_joint[np.asarray(getattr(model, field)) != 0]] = True
        return mask

    # A hinge's or slide's armature enters the metric; its spring and damper enter the
    # scene when asked (`Scene.from_mjcf(..., passive=True)`); a ball's or free joint's do not.
    kept = screw if passive else np.zeros(model.njnt, bool)
    joints_where((np.asarray(model.jnt_stiffness) != 0) & ~kept, "stiffness")
    joints_where(dofs_where("dof_damping") & ~kept, "damping")
    joints_where(dofs_where("dof_frictionloss"), "friction loss")
    what = "armature (rotor inertia, in MuJoCo's mass matrix) of ball/free joint"
    joints_where(dofs_where("dof_armature") & ~screw, what)
    if np.any(np.asarray(model.body_gravcomp) != 0):
        ignored.append("gravity compensation (body gravcomp)")
    if model.opt.density != 0 or model.opt.viscosity != 0:
        ignored.append("fluid forces (option density/viscosity)")
    if model.nflex:
        ignored.append(f"{model.nflex} flex(es)")
    inactive = [i for i in range(model.neq) if not bool(model.eq_active0[i])]
    if inactive:
        ignored.append(f"inactive joint coupling(s) {_names(model, 'equality', inactive)}")
    return ignored


def parts_from_mjmodel(model, *, passive: bool = False) -> ModelParts:
    """The parts of the tree of a compiled `mujoco.MjModel` (see the module docstring).

    **Arguments:**

    - `model`: the `mujoco.MjModel`.
    - `passive`: whether the joints' springs and dampers will be used (not warned about).

    **Returns:**

    The `ModelParts`.
    """
    roots = _check_unsupported(model, passive)
    root = roots[0]
    # Trees attached to the world by joints (not a free joint), or several trees, hang from
    # the world, which becomes the base: held fixed, it enters no equation of the shape, so
    # any mass serves.
    attached = len(roots) > 1 or (bool(model.body_jntnum[root]) and not _free_root(model, root))

    def rigid_body(b):
        name = _name(model, "body", b)
        R = _quat_to_matrix(model.body_iquat[b])
        inertia = R @ np.diag(model.body_inertia[b]) @ R.T
        try:
            return RigidBody(float(model.body_mass[b]), np.array(model.body_ipos[b]), inertia)
        except ValueError as e:
            raise ValueError(f"body '{name}': {e}") from e

    if attached:
        base, names, index, first = world_stand_in(), [WORLD], {0: 0}, root
    else:
        if model.body_mass[root] < _MINVAL:
            raise ValueError(
                f"the root body '{_name(model, 'body', root)}' has no mass; it becomes "
                "bundledyn's floating base, which must be a rigid body with mass. Give it an "
                "<inertial> (or geoms with mass), or remove it so that its child is the root."
            )
        base, names, index, first = (
            rigid_body(root),
            [_name(model, "body", root)],
            {root: 0},
            root + 1,
        )
    welded = {}  # MuJoCo body welded away -> (bundledyn body, its pose in that body)
    links = []
    refs = []
    armature, damping, stiffness, rest = [], [], [], []
    coordinate = {}  # hinge or slide joint -> its shape coordinate
    for b in range(first, model.nbody):
        p = int(model.body_parentid[b])
        local = _pose_np(model.body_pos[b], model.body_quat[b])
        if attached and _free_root(model, b):
            # Its free joint sets the whole pose from qpos: the home placement is the home
            # position (qpos0), unturned, so that the ball joint's turn is qpos's quaternion.
            local = _pose_np(model.body_pos[b], np.array([1.0, 0.0, 0.0, 0.0]))
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
        if attached and parent == 0 and not joints:
            # Welded to the held world (a static target, a mount): it never moves.
            welded[b] = (parent, placement)
            continue
        for j in joints:
            dof = int(model.jnt_dofadr[j])
            if int(model.jnt_type[j]) == _FREE and np.any(model.qpos0[model.jnt_qposadr[j] :][:3]):
                refs.append(f"'{_name(model, 'joint', j)}' (free, home position)")
            if int(model.jnt_type[j]) not in (_HINGE, _SLIDE):
                dof = 6 if int(model.jnt_type[j]) == _FREE else 3
                for values in (armature, damping, stiffness, rest):
                    values += [0.0] * dof
                continue
            address = int(model.jnt_qposadr[j])
            coordinate[j] = len(armature)
            armature.append(float(model.dof_armature[dof]))
            damping.append(float(model.dof_damping[dof]))
            stiffness.append(float(model.jnt_stiffness[j]))
            rest.append(float(model.qpos_spring[address] - model.qpos0[address]))
            if model.qpos0[address] != 0.0:
                refs.append(f"'{_name(model, 'joint', j)}' (ref {model.qpos0[address]:g})")
        index[b] = len(links) + 1
        names.append(_name(model, "body", b))
        links.append(Link(rigid_body(b), _body_joint(model, b, joints), parent, placement))
    ignored = _ignored_elements(model, passive)
    root_pose = _root_pose(model, root, attached)
    if ignored:
        warnings.warn(
            "bundledyn keeps the kinematic tree, the inertias, the rotor inertia of hinges "
            "and slides and, when asked, the linear springs and dampers of joints and tendons "
            "(fixed, or spatial from site to site); ignored from the MuJoCo model: "
            + "; ".join(ignored)
            + ".",
            stacklevel=4,
        )
    if refs:
        warnings.warn(
            "joint(s) " + ", ".join(refs) + " have a non-zero reference position: bundledyn's "
            "coordinate is q = qpos - qpos0, zero at the home pose. Pass qpos0=model.qpos0 to "
            "`bundledyn.state_from_mujoco` / `bundledyn.state_to_mujoco`.",
            stacklevel=4,
        )
    return ModelParts(
        base, tuple(links), tuple(names), model,
        armature=np.array(armature, dtype=float), damping=np.array(damping, dtype=float),
        stiffness=np.array(stiffness, dtype=float), spring_rest=np.array(rest, dtype=float),
        tendons=_fixed_tendons(model, coordinate, len(armature)), ignored=tuple(ignored),
        couplings=_couplings(model, coordinate),
        root_pose=root_pose,
        spatial_tendons=_spatial_tendons(model, index, welded, root_pose)
        if passive else (),
    )  # fmt: skip


def _spatial_tendons(model, index, welded, root_pose) -> tuple[SpatialTendon, ...]:
    """The site-to-site tendons with a spring or a damper, each site placed in the frame of
    its bundledyn body (`index`; a welded-away body through `welded`'s offsets; the world
    through the held base's pose `root_pose`)."""
    tendons = []
    for i in range(model.ntendon):
        if _fixed_tendon(model, i) or not _tendon_is_passive(model, i):
            continue
        bodies, points = [], []
        for w in _wraps(model, i):
            site = int(model.wrap_objid[w])
            body, point = _site_place(model, site, index, welded, root_pose)
            bodies.append(body)
            points.append(point)
        tendons.append(
            SpatialTendon(
                _name(model, "tendon", i), tuple(bodies), np.stack(points),
                float(model.tendon_stiffness[i]), float(model.tendon_damping[i]),
                float(np.ravel(model.tendon_lengthspring[i])[0]),
            )
        )  # fmt: skip
    return tuple(tendons)


def _site_place(model, site: int, index, welded, root_pose):
    """The bundledyn body of a site and its place in that body's frame."""
    b, point = int(model.site_bodyid[site]), np.append(model.site_pos[site], 1.0)
    if b in index:
        return index[b], point[:3]
    if b in welded:
        body, offset = welded[b]
        return body, (offset @ point)[:3]
    if b == 0 and root_pose is not None:  # the world, where the base is held in it
        return 0, (np.linalg.inv(root_pose) @ point)[:3]
    raise ValueError(
        f"site '{_name(model, 'site', site)}' of a tendon with a spring or a damper is on "
        "the world, and the model's root floats: the tendon would pull the tree toward a "
        "point of the world, an external force bundledyn's tendons do not carry. Put the "
        "site on a body of the tree, or give the tendon no stiffness and damping."
    )


def _root_pose(model, root: int, attached: bool) -> np.ndarray | None:
    """Where the base is held: the world's frame for a root attached by joints, the root's
    pose for a welded one (no joint), None (floating) for a free root."""
    if attached:
        return np.eye(4)
    if model.body_jntnum[root]:
        return None
    return _pose_np(model.body_pos[root], model.body_quat[root])


def _couplings(model, coordinate: dict[int, int]):
    """The active joint equalities as `(dependent, independent, polycoef)` of shape
    coordinates (inactive ones are listed among the ignored elements)."""
    couplings = []
    for i in range(model.neq):
        if int(model.eq_type[i]) != _EQ_JOINT or not bool(model.eq_active0[i]):
            continue
        dependent, independent = int(model.eq_obj1id[i]), int(model.eq_obj2id[i])
        couplings.append(
            (
                coordinate[dependent],
                None if independent < 0 else coordinate[independent],
                np.array(model.eq_data[i][:5], dtype=float),
            )
        )
    return tuple(couplings)
