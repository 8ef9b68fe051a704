"""The parameter error, independent of both fitters: each fitted model's bodies are read
as MuJoCo models (mass, centre, inertia), turned into pseudo-inertias here, and compared
with the truth's after projecting out the directions no method can determine
(`null_directions`, built from the geometry).
"""

import numpy as np

from benchmarks.identification.cases import Case


def pseudo_inertia(mass, com, inertia):
    """P = [[Σ_c + m c cᵀ, m c], [m cᵀ, m]] from a mass, centre and inertia about it."""
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia + mass * np.outer(com, com)
    P = np.zeros((4, 4))
    P[:3, :3], P[:3, 3], P[3, :3], P[3, 3] = sigma, mass * com, mass * com, mass
    return P


def model_pseudo_inertias(model, names):
    """The pseudo-inertias of the bodies `names` of a compiled MuJoCo model, `(k, 4, 4)`."""
    import mujoco

    out = []
    for name in names:
        b = model.body(name)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, b.iquat)
        R = R.reshape(3, 3)
        out.append(pseudo_inertia(b.mass[0], b.ipos, R @ np.diag(b.inertia) @ R.T))
    return np.stack(out)


def model_with(case: Case, P):
    """The case's MuJoCo model with the fitted bodies' pseudo-inertias `P` `(k, 4, 4)`."""
    import mujoco

    spec = mujoco.MjSpec.from_string(case.mjcf)
    for name, Pb in zip(case.bodies, P, strict=True):
        m = Pb[3, 3]
        c = Pb[:3, 3] / m
        sigma_c = Pb[:3, :3] - m * np.outer(c, c)
        inertia = np.trace(sigma_c) * np.eye(3) - sigma_c
        moments, axes = np.linalg.eigh(inertia)
        axes[:, 2] *= np.sign(np.linalg.det(axes))
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, axes.reshape(-1))
        body = spec.body(name)
        body.explicitinertial = True
        body.mass, body.ipos, body.iquat, body.inertia = m, c, quat, moments
        body.fullinertia = [np.nan, 0, 0, 0, 0, 0]
    return spec.compile()


def _placement(model, body):
    """The 4×4 placement of `body` in its parent's frame."""
    import mujoco

    T = np.eye(4)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, model.body_quat[body])
    T[:3, :3], T[:3, 3] = R.reshape(3, 3), model.body_pos[body]
    return T


def _line(anchor, axis):
    """The three δP of mass on the line through `anchor` along `axis` (body frame)."""
    u, w = np.append(anchor, 1.0), np.append(axis / np.linalg.norm(axis), 0.0)
    return [np.outer(u, u), np.outer(u, w) + np.outer(w, u), np.outer(w, w)]


def _fixed_axis(model, joint, k, body):
    """The directions of a body turning about an axis fixed in space that its dynamics does
    not see: all but its moment about the axis and, under gravity, its first moment across
    the axis (the only three functionals it enters)."""
    w = np.append(model.jnt_axis[joint], 0.0)
    w[:3] /= np.linalg.norm(w[:3])
    E = np.hstack([np.eye(3), -model.jnt_pos[joint][:, None]])  # p̃ -> p - anchor
    seen = [E.T @ (np.eye(3) - np.outer(w[:3], w[:3])) @ E]  # the moment about the axis
    across = np.linalg.svd(w[None, :3])[2][1:]  # two unit vectors across the axis
    for b in across:  # the first moment about the anchor, across the axis
        F = np.outer(E.T @ b, np.eye(4)[3])
        seen.append(0.5 * (F + F.T))
    basis = np.stack([B.reshape(-1) for B in _symmetric_basis()], 1)  # (16, 10)
    functionals = np.stack([basis.T @ F.reshape(-1) for F in seen])  # (3, 10)
    hidden = np.linalg.svd(functionals)[2][len(seen) :]  # (7, 10)
    directions = []
    for v in hidden:
        D = np.zeros((k, 4, 4))
        D[body] = (basis @ v).reshape(4, 4)
        directions.append(D)
    return directions


def _symmetric_basis():
    basis = []
    for i in range(4):
        for j in range(i, 4):
            E = np.zeros((4, 4))
            E[i, j] = E[j, i] = 1.0
            basis.append(E)
    return basis


def null_directions(case: Case, P_true):
    """The directions of the fitted bodies' pseudo-inertias `(k·16, r)` that the data of
    `case` cannot determine, built from the geometry (not from either fitter):

    - each hinge between two fitted bodies: mass on its axis line, added to the child and
      taken from the parent (three directions, as `_hinge_regroupings` in
      tests/test_identify_mujoco.py); a ball joint, or hinges crossed at one point (a
      universal joint): mass at that point (one direction);
    - a body turning about an axis fixed in space (the arm's upper link): everything but
      its moment about the axis and, under gravity, its first moment across the axis
      (the only three functionals its dynamics sees);
    - the torque-free body with known mass: the scale of its inertia about its centre.
    """
    import mujoco

    model = mujoco.MjModel.from_xml_string(case.mjcf)
    k = len(case.bodies)
    index = {name: i for i, name in enumerate(case.bodies)}
    directions = []
    if case.name == "tumble":
        m, c = P_true[0, 3, 3], P_true[0, :3, 3] / P_true[0, 3, 3]
        D = np.zeros((1, 4, 4))
        D[0, :3, :3] = P_true[0, :3, :3] - m * np.outer(c, c)
        directions.append(D)
    for child in range(1, model.nbody):
        joints = [j for j in range(model.njnt) if model.jnt_bodyid[j] == child]
        kinds = [model.jnt_type[j] for j in joints]
        if not joints or mujoco.mjtJoint.mjJNT_FREE in kinds:
            continue
        parent = model.body_parentid[child]
        name, parent_name = model.body(child).name, model.body(parent).name
        if parent_name not in index:  # the parent is welded to the world
            if kinds != [mujoco.mjtJoint.mjJNT_HINGE]:
                raise ValueError(f"{name}: only a hinge on a welded parent is scored")
            directions += _fixed_axis(model, joints[0], k, index[name])
            continue
        if kinds == [mujoco.mjtJoint.mjJNT_HINGE]:  # mass on the hinge's axis line
            moved = _line(model.jnt_pos[joints[0]], model.jnt_axis[joints[0]])
        else:  # a ball or crossed hinges: mass at the joint's centre
            u = np.append(model.jnt_pos[joints[0]], 1.0)
            moved = [np.outer(u, u)]
        T = _placement(model, child)
        for delta in moved:
            D = np.zeros((k, 4, 4))
            D[index[name]], D[index[parent_name]] = delta, -T @ delta @ T.T
            directions.append(D)
    if not directions:
        return np.zeros((k * 16, 0))
    return np.stack([D.reshape(-1) for D in directions], axis=1)


def relative_errors(P_fit, P_true, directions):
    """Each body's ‖P̂ − P‖_F / ‖P‖_F after projecting the difference (all bodies together)
    onto the orthogonal complement of `directions`."""
    difference = (np.asarray(P_fit) - np.asarray(P_true)).reshape(-1)
    if directions.shape[1]:
        difference = (
            difference - directions @ np.linalg.lstsq(directions, difference, rcond=None)[0]
        )
    difference = difference.reshape(np.shape(P_true))
    return np.linalg.norm(difference, axis=(1, 2)) / np.linalg.norm(P_true, axis=(1, 2))
