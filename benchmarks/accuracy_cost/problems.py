"""The six scenes of the accuracy–cost sweep, each with its initial state, horizon and
which invariants it keeps."""

import dataclasses
import warnings

import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from benchmarks._models import chain_scene

ATOL_RATIO = 1e-3  # atol = rtol * ATOL_RATIO for every adaptive method


@dataclasses.dataclass(frozen=True)
class Problem:
    """A scene, its initial state and horizon, and which invariants it has."""

    name: str
    title: str
    scene: bd.Scene
    state: bd.State
    t1: float
    energy: bool  # energy conserved (no prescribed motion, no damping)
    momentum: bool  # spatial momentum conserved (no external wrench)
    stiff: bool = False
    atol_ratio: float = ATOL_RATIO  # atol = rtol * atol_ratio


def moving(d, xi=(0.3, 0.2, -0.4, 0.1, 0.0, 0.2), qdot=0.5, q=0.1):
    """A state of `d` shape coordinates, all moving."""
    return bd.State(jnp.eye(4), q * jnp.ones(d), jnp.asarray(xi), qdot * jnp.ones(d))


def mjcf_chain():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the joint refs; handled through qpos0
        return bd.Multibody.from_mjcf(bd.models / "chain5.xml")


def dzhanibekov():
    body = bd.RigidBody(1.0, [0.0, 0.0, 0.0], np.diag([1.0, 2.0, 3.0]))
    omega = np.array([0.01, 2.0, 0.01])  # near the intermediate axis
    return Problem(
        "dzhanibekov",
        "torque-free asymmetric body near its intermediate axis (Dzhanibekov), 20 s",
        bd.Scene(body),
        bd.State(jnp.eye(4), (), jnp.concatenate([omega, jnp.zeros(3)])),
        20.0,
        True,
        True,
    )


def chain():
    system = mjcf_chain()
    return Problem(
        "chain",
        "free-floating MJCF chain (chain5.xml: hinge, ball, universal, slide, composite), 2 s",
        bd.Scene(system),
        moving(system.shape_dim),
        2.0,
        True,
        True,
    )


def affine_spring():
    body = bd.AffineBody(3.0, 3.0 / 5.0 * np.diag([0.5**2, 0.3**2, 0.2**2]))
    scene = bd.Scene(body, (bd.ShapeSpring(40.0 * jnp.ones(6)),))
    return Problem(
        "affine_spring",
        "affine body on an isotropic shape spring, 1 s",
        scene,
        bd.State(
            jnp.eye(4),
            0.1 * jnp.arange(6.0) / 6,
            jnp.array([0.5, -0.3, 0.8, 0.1, 0.0, 0.0]),
            0.3 * jnp.ones(6),
        ),
        1.0,
        True,
        True,
    )


def falling_cat():
    half = bd.RigidBody(1.5, [0.0, 0.0, 0.0], np.diag([0.02, 0.08, 0.08]))
    offset = np.eye(4)
    offset[0, 3] = 0.5
    cat = bd.Multibody(
        half, [bd.Link(half, bd.Universal([0, 0, 1], [0, 1, 0], [-0.25, 0, 0]), 0, offset)]
    )

    def bend(t):
        phase = 2 * jnp.pi * t
        return 0.6 * jnp.array([jnp.sin(phase), 1.0 - jnp.cos(phase)])

    scene = bd.Scene(cat, shape=bd.Prescribed(bend))
    q0, qdot0 = scene.shape.at(0.0)
    state = bd.State(jnp.eye(4), q0, -bd.connection(cat, q0) @ qdot0, qdot0)
    return Problem(
        "falling_cat",
        "falling cat: prescribed shape loop at zero momentum, 1 s",
        scene,
        state,
        1.0,
        False,
        True,
    )


def gravity_gradient_chain():
    system = chain_scene(10).system
    effect = bd.BodywiseGravityGradient(3.986e14, (-7.0e6, 0.0, 0.0))
    # Released at rest 630 km above the centre: it falls 1.6 km in 20 s while the gradient
    # (~1e-6 s⁻²) turns and stretches it. An orbital 7.5 km/s would make the Galilean
    # cancellations in (2.6)–(2.7) lose digits: RKMK54 then took 47,073 steps at rtol 1e-9.
    state = bd.State(jnp.eye(4), 0.2 * jnp.ones(9), jnp.zeros(6), 0.05 * jnp.ones(9))
    return Problem(
        "gravity_gradient",
        "10-body hinge chain falling in a central field (gravity gradient), 20 s",
        bd.Scene(system, (effect,)),
        state,
        20.0,
        True,
        False,
        # Forces in a field centred 7e6 m away carry rounding of ~1e-15 in absolute terms;
        # an atol below that makes the steps noise-limited (42,265 steps at rtol 1e-13).
        atol_ratio=1.0,
    )


def stiff_chain():
    system = chain_scene(3).system
    # Joint 1 is a spring 10⁶ times stiffer than joint 2, damped: a fast mode ~10³ times
    # faster than the slow one, decaying at ~10³ s⁻¹. It starts at rest at its equilibrium,
    # so after a short transient the motion is slow and an explicit method's step is bounded
    # by stability, not accuracy: the classic stiff case.
    effects = (bd.ShapeSpring(jnp.array([1.0e6, 1.0])), bd.ShapeDamper(jnp.array([300.0, 0.0])))
    state = bd.State(
        jnp.eye(4),
        jnp.array([0.0, 0.3]),
        jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]),
        jnp.array([0.0, 0.5]),
    )
    return Problem(
        "stiff",
        "3-body chain, one damped spring 10⁶ times stiffer than the other, 0.5 s",
        bd.Scene(system, effects),
        state,
        0.5,
        False,
        True,
        stiff=True,
    )


PROBLEMS = {
    "dzhanibekov": dzhanibekov,
    "chain": chain,
    "affine_spring": affine_spring,
    "falling_cat": falling_cat,
    "gravity_gradient": gravity_gradient_chain,
    "stiff": stiff_chain,
}
