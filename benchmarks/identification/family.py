"""The identification benchmark's generated family: systems written from a seed, none tuned for.

- `tree`: a floating tree of 2–8 bodies without gravity, each attached to an earlier one by
  a hinge, a ball or a universal joint (two hinges, crossed at one point) on random axes;
  every hinge is driven (torques known), ball joints are not.
- `arm`: a fixed-base arm of 2–6 links on a welded base, under gravity, each link hanging
  below the last on a hinge of random axis, every hinge driven.

Every body has a random mass, a full inertia (a random solid ellipsoid's, turned at random)
and a centre off its joint axes. A member is a `Case`, like the three named data sets, so
the benchmark records, fits and scores it the same way; its torques and starts come from
`cases.torque` and `cases.initial_velocity`, and its nominal inertias are the truth's
scaled by factors drawn from the seed (8–35 % off).
"""

import numpy as np

from benchmarks.identification.cases import Case

KINDS = ("tree", "arm")
BODIES = {"tree": (2, 8), "arm": (2, 6)}  # the fewest and the most, both included
JOINTS = ("hinge", "ball", "universal")


def _rotation(rng):
    """A random rotation (the Q of a Gaussian matrix's QR, signs fixed, det +1)."""
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q * np.linalg.det(Q)


def _unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _numbers(x):
    return " ".join(f"{v:.6g}" for v in np.ravel(x))


def _inertial(rng):
    """A body's `<inertial>`: mass 0.5–2 kg, the inertia of a solid ellipsoid of semi-axes
    5–20 cm turned at random, the centre up to 10 cm off the body's origin on each axis."""
    mass = rng.uniform(0.5, 2.0)
    a, b, c = rng.uniform(0.05, 0.2, 3)
    moments = mass / 5 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    R = _rotation(rng)
    inertia = R @ np.diag(moments) @ R.T
    full = [
        inertia[0, 0],
        inertia[1, 1],
        inertia[2, 2],
        inertia[0, 1],
        inertia[0, 2],
        inertia[1, 2],
    ]
    centre = rng.uniform(-0.1, 0.1, 3)
    return f'<inertial pos="{_numbers(centre)}" mass="{mass:.6g}" fullinertia="{_numbers(full)}"/>'


def _joints(rng, kind: str, name: str) -> tuple[list[str], list[str]]:
    """A body's joint elements of `kind` and the names of its hinges (each driven)."""
    if kind == "ball":
        return [f'<joint name="{name}" type="ball"/>'], []
    first = _unit(rng)
    if kind == "hinge":
        return [f'<joint name="{name}" type="hinge" axis="{_numbers(first)}"/>'], [name]
    second = np.cross(first, _unit(rng))
    second /= np.linalg.norm(second)
    names = [f"{name}a", f"{name}b"]
    return [
        f'<joint name="{n}" type="hinge" axis="{_numbers(axis)}"/>'
        for n, axis in zip(names, (first, second), strict=True)
    ], names


def _tree(rng, kind: str, n: int):
    """The bodies' parents, joint kinds and offsets from their parents."""
    if kind == "arm":
        parents = list(range(-1, n - 1))
        joints = ["hinge"] * n
    else:
        parents = [-1] + [int(rng.integers(0, i)) for i in range(1, n)]
        joints = ["free"] + [str(rng.choice(JOINTS)) for _ in range(1, n)]
        if not any(j in ("hinge", "universal") for j in joints):
            joints[1] = "hinge"  # a driven joint: the torques fix the mass scale
    offsets = [0.3 * _unit(rng) for _ in range(n)]
    if kind == "arm":  # each link hangs below the last (near rest at the home pose)
        offsets = [0.3 * _downward(rng) for _ in range(n)]
    return parents, joints, offsets


def _downward(rng):
    """A unit vector within some 30° of straight down."""
    v = np.append(0.3 * rng.normal(size=2), -1.0)
    return v / np.linalg.norm(v)


def _mjcf(kind: str, n: int, rng) -> tuple[str, tuple[str, ...]]:
    """The member's MJCF and its fitted bodies' names."""
    parents, joints, offsets = _tree(rng, kind, n)
    names = [f"b{i}" for i in range(n)]
    inner: dict[int, list[str]] = {i: [] for i in range(-1, n)}
    driven: list[str] = []
    for i in reversed(range(n)):
        if joints[i] == "free":
            elements = ["<freejoint/>"]
        else:
            elements, hinges = _joints(rng, joints[i], f"j{i}")
            driven = hinges + driven
        pos = "0 0 0" if parents[i] < 0 else _numbers(offsets[i])
        body = [f'<body name="{names[i]}" pos="{pos}">', *elements, _inertial(rng)]
        inner[parents[i]].insert(0, "\n".join([*body, *inner[i], "</body>"]))
    if kind == "arm":  # the first link hangs from a base welded to the world
        # (bundledyn's held base is a body with mass, as the named arm's)
        base = '<inertial pos="0 0 0" mass="5" diaginertia="0.1 0.1 0.1"/>'
        top = ['<body name="base" pos="0 0 1.5">', base, *inner[-1], "</body>"]
        option = '<option integrator="RK4" timestep="2e-4"/>'
    else:
        top = inner[-1]
        option = '<option gravity="0 0 0" integrator="RK4" timestep="2e-4"/>'
    motors = "\n".join(f'<motor joint="{j}" gear="1"/>' for j in driven)
    mjcf = "\n".join(
        [f'<mujoco model="{kind}">', option, "<worldbody>", *top, "</worldbody>",
         f"<actuator>\n{motors}\n</actuator>", "</mujoco>"]
    )  # fmt: skip
    return mjcf, tuple(names)


def member(kind: str, seed: int, *, bodies: int | None = None) -> Case:
    """The family's member `kind` (`"tree"` or `"arm"`) of `seed`, with `bodies` bodies
    (default: drawn from the seed within `BODIES[kind]`)."""
    if kind not in KINDS:
        raise ValueError(f"`kind` must be one of {KINDS}, got {kind!r}.")
    rng = np.random.default_rng([KINDS.index(kind), seed])
    low, high = BODIES[kind]
    n = int(rng.integers(low, high + 1)) if bodies is None else bodies
    mjcf, names = _mjcf(kind, n, rng)
    factors = tuple(float(f) for f in rng.uniform(0.75, 1.35, n))
    floating = kind == "tree"
    what = "floating tree, no gravity" if floating else "arm on a welded base, gravity"
    return Case(
        f"{kind}{seed}", mjcf, names, 4.0, 2.0, floating, "inputs",
        f"generated {what}, {n} bodies (seed {seed})", member=seed, factors=factors,
    )  # fmt: skip


def family(count: int) -> list[Case]:
    """The first `count` members of each kind (seeds 0, 1, …)."""
    return [member(kind, seed) for seed in range(count) for kind in KINDS]
