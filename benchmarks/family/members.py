"""The family of models: random trees the benchmark was not tuned on, and published ones.

Each structure is an MJCF model both simulators load: bundledyn through
`bd.Multibody.from_mjcf`, MuJoCo through its own parser. Random trees are drawn from a
seed: a free base and n − 1 boxes (masses 0.5–2 kg, sides 0.05–0.3 m), each hung from a
random earlier body at a random offset, by a hinge about a random axis, a ball joint, or
two hinges about random axes at different anchors (a `Composite` joint). The published
model is gymnasium's humanoid (its tree: contacts, limits, actuators, springs, dampers and
gravity switched off in MuJoCo; none of them named in bundledyn's scene). Each structure
runs at two energies: joint rates and base rates of about 0.5 and 2 rad/s.
"""

from typing import NamedTuple

import numpy as np

from benchmarks._output import ROOT

HUMANOID = ROOT / "tests" / "models" / "gymnasium" / "humanoid.xml"
# Structures: (bodies, joint kind); every size and kind, chains and trees.
STRUCTURES = (
    (5, "hinge"),
    (10, "hinge"),
    (20, "hinge"),
    (5, "ball"),
    (10, "ball"),
    (5, "composite"),
    (10, "composite"),
    (20, "mixed"),
)
RATES = {"low": 0.5, "high": 2.0}  # rad/s, the scale of the initial joint and base rates


class Member(NamedTuple):
    """One model of the family at one energy: its `name`, its MJCF `xml` (gravity off, RK4),
    its `bodies`, `kind` of joints and `rate` (the scale of its initial velocities)."""

    name: str
    xml: str
    bodies: int
    kind: str
    rate: float


def _unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _fmt(v):
    return " ".join(f"{x:.6g}" for x in np.atleast_1d(v))


def _joints(kind, rng, anchor):
    """The MJCF joints of one body of `kind` (a mixed tree draws one kind per body)."""
    if kind == "mixed":
        kind = ("hinge", "ball", "composite")[rng.integers(3)]
    if kind == "hinge":
        return f'<joint type="hinge" axis="{_fmt(_unit(rng))}" pos="{_fmt(anchor)}"/>'
    if kind == "ball":
        return f'<joint type="ball" pos="{_fmt(anchor)}"/>'
    second = anchor + 0.05 * _unit(rng)  # apart, so that the axes do not meet (no Universal)
    return (
        f'<joint type="hinge" axis="{_fmt(_unit(rng))}" pos="{_fmt(anchor)}"/>'
        f'<joint type="hinge" axis="{_fmt(_unit(rng))}" pos="{_fmt(second)}"/>'
    )


def _box(rng):
    mass = rng.uniform(0.5, 2.0)
    a, b, c = rng.uniform(0.05, 0.3, 3)
    inertia = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    com = 0.02 * rng.normal(size=3)
    return f'<inertial pos="{_fmt(com)}" mass="{mass:.6g}" diaginertia="{_fmt(inertia)}"/>'


def random_tree(bodies: int, kind: str, seed: int) -> str:
    """MJCF of a random free-floating tree of `bodies` boxes joined by joints of `kind`
    (`"hinge"`, `"ball"`, `"composite"` or `"mixed"`), gravity off."""
    rng = np.random.default_rng(seed)
    parents = [-1] + [int(rng.integers(max(0, i - 2), i)) for i in range(1, bodies)]
    children = {i: [j for j in range(bodies) if parents[j] == i] for i in range(bodies)}

    def body(i):
        offset = rng.uniform(0.2, 0.4) * _unit(rng) if i else np.zeros(3)
        joint = "<freejoint/>" if i == 0 else _joints(kind, rng, -0.5 * offset)
        inner = "".join(body(j) for j in children[i])
        return f'<body name="b{i}" pos="{_fmt(offset)}">{joint}{_box(rng)}{inner}</body>'

    return (
        '<mujoco><option gravity="0 0 0" timestep="0.01" integrator="RK4"/>'
        f"<worldbody>{body(0)}</worldbody></mujoco>"
    )


def members(quick: bool) -> list[Member]:
    """The family: every structure at both energies, and the humanoid at both (the quick
    run: the first structure at the low energy only)."""
    out = []
    for seed, (bodies, kind) in enumerate(STRUCTURES[:1] if quick else STRUCTURES):
        xml = random_tree(bodies, kind, seed)
        for energy, rate in list(RATES.items())[: 1 if quick else None]:
            out.append(Member(f"tree {seed}: {bodies} {kind}, {energy}", xml, bodies, kind, rate))
    if not quick:
        for energy, rate in RATES.items():
            out.append(Member(f"humanoid, {energy}", HUMANOID.read_text(), 13, "hinge", rate))
    return out


def mujoco_model(member: Member, dt: float):
    """MuJoCo's model of `member` with step `dt` (RK4), its tree only: no gravity, contacts,
    limits, actuators, springs or dampers."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(member.xml)
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= (
        off.mjDSBL_CONSTRAINT | off.mjDSBL_ACTUATION | off.mjDSBL_SPRING | off.mjDSBL_DAMPER
    )
    model.opt.gravity[:] = 0.0
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = dt
    return model


def initial_qpos_qvel(model, rate: float, seed: int):
    """MuJoCo's qpos and qvel of a tumbling start: joint angles of about 0.3 rad from the
    home pose (ball joints turned by as much), base and joint rates of about `rate`."""
    rng = np.random.default_rng(1000 + seed)
    qpos, qvel = model.qpos0.copy(), rate * rng.normal(size=model.nv)
    for j in range(1, model.njnt):
        a = model.jnt_qposadr[j]
        if model.jnt_type[j] == 1:  # ball: a quaternion turned by about 0.3 rad
            w = 0.3 * rng.normal(size=3)
            angle = np.linalg.norm(w)
            qpos[a : a + 4] = np.r_[np.cos(angle / 2), np.sin(angle / 2) * w / angle]
        else:
            qpos[a] += 0.3 * rng.normal()
    return qpos, qvel
