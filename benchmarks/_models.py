"""The model family both simulators run: free chains of n boxes written once as MJCF.

`chain_mjcf(n)` is loaded by bundledyn (`chain_scene`, through `bd.Multibody.from_mjcf`)
and by MuJoCo (`mujoco_model`): the same bodies, inertias and joints in both.
"""

import bundledyn as bd


def chain_mjcf(n: int) -> str:
    """MJCF of a free chain of n boxes (hinges alternate y and z), gravity off."""
    bodies = ""
    for i in reversed(range(n)):
        mass, b = 1.0 + 0.3 * i, 0.1 + 0.02 * i
        a, c = 0.5, 0.08
        inertia = [
            mass / 12 * (b * b + c * c),
            mass / 12 * (a * a + c * c),
            mass / 12 * (a * a + b * b),
        ]
        joint = (
            '<freejoint name="root"/>'
            if i == 0
            else f'<joint type="hinge" axis="{"0 0 1" if i % 2 else "0 1 0"}" pos="-0.25 0 0"/>'
        )
        inner = bodies
        bodies = (
            f'<body name="b{i}" pos="{0.5 if i else 0.0} 0 0">{joint}'
            f'<inertial pos="{0.02 * i} 0.01 0" mass="{mass}" '
            f'diaginertia="{inertia[0]} {inertia[1]} {inertia[2]}"/>{inner}</body>'
        )
    return (
        '<mujoco><option gravity="0 0 0" timestep="0.01" integrator="RK4"/>'
        f"<worldbody>{bodies}</worldbody></mujoco>"
    )


def chain_scene(n: int) -> bd.Scene:
    """The bundledyn scene of `chain_mjcf(n)`."""
    return bd.Scene(bd.Multibody.from_mjcf(chain_mjcf(n)))


def initial_state(scene: bd.Scene) -> bd.State:
    """A tumbling state: bent shape, base twist and joint rates all non-zero."""
    import jax.numpy as jnp

    k = jnp.arange(scene.system.shape_dim, dtype=float)
    xi = jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1])
    return bd.State(jnp.eye(4), 0.3 * jnp.sin(k + 1.0), xi, 0.5 * jnp.cos(k))


def mujoco_model(n: int, dt: float):
    """MuJoCo's model of `chain_mjcf(n)` with time step `dt` (RK4)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(chain_mjcf(n))
    model.opt.timestep = dt
    return model
