"""The Whipple bicycle on both sides: sympy's own model (its test `test_kane3.test_bicycle`,
ported from Autolev: `KanesMethod` with three velocity constraints at the front contact and
the pitch as a dependent coordinate) and bundledyn's `WhippleBicycle` (Maggi's equations by
autodiff of the four bodies' placements).

The peer's world has $z$ up, bundledyn's (the paper's) $z$ down; both bodies' frames differ
by a half turn about the forward axis, so the peer's yaw $q_1 = -\\psi$, roll $q_2 = \\phi$,
pitch $q_4 = -\\theta_B$, steer $q_5 = \\delta$ (the same physical steer axis), and its
speeds $(u_2, u_3, u_5, u_1, u_4, u_6) = (\\dot\\phi, \\dot\\theta_B - \\dot\\theta_R,
\\dot\\delta, -\\dot\\psi, -\\dot\\theta_B, -\\dot\\theta_F)$ ($u_3$ is the rear wheel's rate
relative to the frame; bundledyn's $\\theta_R$ is relative to the yawed and rolled frame)."""

import functools

import numpy as np

from benchmarks.nonholonomic.peer import KaneModel

NAME = "Whipple bicycle"
SPEEDS = (4.0, 5.0, 6.5)  # forward speeds (m/s): below, inside and above the self-stable band


def _parameters():
    """sympy's numbers for the benchmark bicycle (`test_kane3`), from Meijaard et al. Table 1."""
    from math import acos, cos, pi, sin, sqrt

    rad_rear, rad_front, trail, wheelbase = 0.3, 0.35, 0.08, 1.02
    hta = pi / 2 - pi / 10
    rake = -(trail * sin(hta) - rad_front * cos(hta))
    frame_x, frame_z, fork_x, fork_z = 0.3, 0.9, 0.9, 0.7
    frame_length = wheelbase * sin(hta) - (rake - (rad_front - rad_rear) * cos(hta))
    frame_cg_norm = (frame_z - rad_rear - (frame_x / sin(hta)) * cos(hta)) * sin(hta)
    frame_cg_par = frame_x / sin(hta) + (frame_z - rad_rear - frame_x / sin(hta) * cos(hta)) * cos(
        hta
    )
    a, b = fork_z - rad_front, wheelbase - fork_x
    c = sqrt(a**2 + b**2)
    fork_length = wheelbase * cos(hta) - (rad_front - rad_rear) * sin(hta)
    fork_cg_norm = rake + c * sin(pi / 2 - hta - acos(a / c))
    fork_cg_par = c * cos((pi / 2 - hta) - acos(a / c)) - fork_length
    return {
        "WFrad": rad_front, "WRrad": rad_rear, "htangle": hta, "forkoffset": rake,
        "forklength": fork_length, "framelength": frame_length, "forkcg1": fork_cg_par,
        "forkcg3": fork_cg_norm, "framecg1": frame_cg_norm, "framecg3": frame_cg_par,
        "Iwr11": 0.0603, "Iwr22": 0.12, "Iwf11": 0.1405, "Iwf22": 0.28,
        "Ifork11": 0.05892, "Ifork22": 0.06, "Ifork33": 0.00708, "Ifork31": 0.00756,
        "Iframe11": 9.2, "Iframe22": 11.0, "Iframe33": 2.8, "Iframe31": -2.4,
        "mfork": 4.0, "mframe": 85.0, "mwf": 3.0, "mwr": 2.0, "g": 9.81,
    }  # fmt: skip


def kane_model(variant=None):
    """sympy's bicycle (`sympy/physics/mechanics/tests/test_kane3.py`), its equations formed.
    Returns the `KaneModel` and, in `holonomic`, the front contact's height."""
    import sympy as sm
    import sympy.physics.mechanics as me

    p = {name: sm.Symbol(name) for name in _parameters()}
    q1, q2, q4, q5 = me.dynamicsymbols("q1 q2 q4 q5")
    u1, u2, u3, u4, u5, u6 = me.dynamicsymbols("u1 u2 u3 u4 u5 u6")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    R = Y.orientnew("R", "Axis", [q2, Y.x])
    Frame = R.orientnew("Frame", "Axis", [q4 + p["htangle"], R.y])
    WR = me.ReferenceFrame("WR")
    TempFrame = Frame.orientnew("TempFrame", "Axis", [-p["htangle"], Frame.y])
    Fork = Frame.orientnew("Fork", "Axis", [q5, Frame.x])
    TempFork = Fork.orientnew("TempFork", "Axis", [-p["htangle"], Fork.y])
    WF = me.ReferenceFrame("WF")

    WR_cont = me.Point("WR_cont")
    WR_mc = WR_cont.locatenew("WR_mc", p["WRrad"] * R.z)
    Steer = WR_mc.locatenew("Steer", p["framelength"] * Frame.z)
    Frame_mc = WR_mc.locatenew("Frame_mc", -p["framecg1"] * Frame.x + p["framecg3"] * Frame.z)
    Fork_mc = Steer.locatenew("Fork_mc", -p["forkcg1"] * Fork.x + p["forkcg3"] * Fork.z)
    WF_mc = Steer.locatenew("WF_mc", p["forklength"] * Fork.x + p["forkoffset"] * Fork.z)
    WF_cont = WF_mc.locatenew(
        "WF_cont", p["WFrad"] * (me.dot(Fork.y, Y.z) * Fork.y - Y.z).normalize()
    )

    Y.set_ang_vel(N, u1 * Y.z)
    R.set_ang_vel(Y, u2 * R.x)
    WR.set_ang_vel(Frame, u3 * Frame.y)
    Frame.set_ang_vel(R, u4 * Frame.y)
    Fork.set_ang_vel(Frame, u5 * Fork.x)
    WF.set_ang_vel(Fork, u6 * Fork.y)
    WR_cont.set_vel(N, 0)
    WR_mc.v2pt_theory(WR_cont, N, WR)
    Steer.v2pt_theory(WR_mc, N, Frame)
    Frame_mc.v2pt_theory(WR_mc, N, Frame)
    Fork_mc.v2pt_theory(Steer, N, Fork)
    WF_mc.v2pt_theory(Steer, N, Fork)
    WF_cont.v2pt_theory(WF_mc, N, WF)

    inertia = me.inertia
    bodies = [
        me.RigidBody("BodyFrame", Frame_mc, Frame, p["mframe"], (inertia(
            TempFrame, p["Iframe11"], p["Iframe22"], p["Iframe33"], 0, 0, p["Iframe31"]
        ), Frame_mc)),
        me.RigidBody("BodyFork", Fork_mc, Fork, p["mfork"], (inertia(
            TempFork, p["Ifork11"], p["Ifork22"], p["Ifork33"], 0, 0, p["Ifork31"]
        ), Fork_mc)),
        me.RigidBody("BodyWR", WR_mc, WR, p["mwr"],
                     (inertia(Frame, p["Iwr11"], p["Iwr22"], p["Iwr11"]), WR_mc)),
        me.RigidBody("BodyWF", WF_mc, WF, p["mwf"],
                     (inertia(Fork, p["Iwf11"], p["Iwf22"], p["Iwf11"]), WF_mc)),
    ]  # fmt: skip
    loads = [(point, -mass * p["g"] * Y.z) for point, mass in (
        (Frame_mc, p["mframe"]), (Fork_mc, p["mfork"]), (WF_mc, p["mwf"]), (WR_mc, p["mwr"])
    )]  # fmt: skip
    constraints = [WF_cont.vel(N) & Y.x, WF_cont.vel(N) & Y.y, WF_cont.vel(N) & Y.z]
    method = me.KanesMethod(
        N,
        q_ind=[q1, q2, q5],
        q_dependent=[q4],
        configuration_constraints=[WF_cont.pos_from(WR_cont) & Y.z],
        u_ind=[u2, u3, u5],
        u_dependent=[u1, u4, u6],
        velocity_constraints=constraints,
        kd_eqs=[q1.diff() - u1, q2.diff() - u2, q4.diff() - u4, q5.diff() - u5],
        constraint_solver="CRAMER",
    )
    method.kanes_equations(bodies, loads)
    values = {p[name]: value for name, value in _parameters().items()}
    return KaneModel(method, constraints, values)


def members(quick):
    """The family: a lean and a steer rate drawn at random, at each forward speed."""
    rng = np.random.default_rng(2026_11_28)
    speeds = SPEEDS[1:2] if quick else SPEEDS
    out = []
    for speed in speeds:
        for _ in range(1 if quick else 2):
            lean, steer_rate = rng.uniform(-0.1, 0.1), rng.normal(0.0, 0.5)
            out.append({"label": f"{speed:g} m/s, lean {lean:+.3f} rad", "variant": None,
                        "speed": speed, "lean": lean, "steer_rate": steer_rate})  # fmt: skip
    return out


def ours_model(variant=None):
    """bundledyn's `WhippleBicycle` with the paper's parameters."""
    import bundledyn as bd

    return bd.WhippleBicycle.benchmark()


def _to_peer(q, qdot):
    """The peer's state $(q_1, q_2, q_5, q_4, u_2, u_3, u_5, u_1, u_4, u_6)$ of bundledyn's
    $(q, \\dot q)$, states along the first axis."""
    psi, phi, pitch, steer = q[:, 2], q[:, 3], q[:, 4], q[:, 5]
    d = qdot
    return np.stack([
        -psi, phi, steer, -pitch,
        d[:, 3], d[:, 4] - d[:, 6], d[:, 5], -d[:, 2], -d[:, 4], -d[:, 7],
    ], axis=1)  # fmt: skip


def _velocities(bike, q, e):
    import jax

    import bundledyn as bd

    return jax.vmap(lambda q, e: bd.constrained_velocities(bike.constraints, q, e, 0.0))(q, e)


def initial_states(bike, speeds, member):
    """`((q, e), the peer's state)` of a member: upright running at its speed, leaning and
    steered, the pitch on the ground (`on_the_ground`)."""
    q, e = bike.steady_motion(member["speed"])
    q = bike.on_the_ground(q.at[3].set(member["lean"]))
    e = e.at[1].set(member["steer_rate"])
    x0 = _to_peer(np.asarray(q)[None], np.asarray(_velocities(bike, q[None], e[None])))[0]
    return (q, e), x0


@functools.cache
def _solver():
    """The compiled solve (made once: a new `filter_jit` would trace again at every call),
    returning the saved coordinates and velocities."""
    import diffrax
    import equinox as eqx

    import bundledyn as bd

    @eqx.filter_jit
    def solve(bike, y0, ts, rtol):
        q, e = diffrax.diffeqsolve(
            bd.NonholonomicTerm(bike), diffrax.Dopri8(), ts[0], ts[-1], None, y0,
            saveat=diffrax.SaveAt(ts=ts), max_steps=100_000,
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol),
        ).ys  # fmt: skip
        return q, _velocities(bike, q, e)

    return solve


def simulate(bike, y0, ts, rtol):
    """bundledyn's trajectory at `ts`, as the peer's states `(n, 10)`."""
    q, qdot = _solver()(bike, y0, ts, rtol)
    return _to_peer(np.asarray(q), np.asarray(qdot))


def disagreement(ours, theirs):
    """The largest difference of the angles $(\\psi, \\phi, \\theta_B, \\delta)$ and the rates
    $(\\dot\\phi, \\dot\\delta)$ at the saves."""
    kept = [0, 1, 2, 3, 4, 6]
    return float(np.max(np.abs(ours[:, kept] - theirs[:, kept])))
