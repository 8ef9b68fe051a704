"""The mujoco.sysid side of the identification benchmark (MuJoCo ≥ 3.4's `mujoco.sysid`).

Its documented path, on the same noisy records as bundledyn: each fitted body an
`InertiaType.Pseudo` parameter (the same log-Cholesky coordinates of the pseudo-inertia),
the nominal MJCF (same start), the measured qpos and qvel as state signals, the controls
each MuJoCo step held, `build_residual_fn` (MuJoCo's rollouts, residuals scaled per channel
by the measured data's magnitude) over the whole record (single shooting) or over pieces
each started from its measured first state (its multiple-shooting option), and
`optimize(optimizer="mujoco")` (`mujoco.minimize.least_squares`, finite-difference
Jacobians) at its default iteration cap, then `calculate_intervals` at the optimum.

Three departures from the defaults, each needed or to its advantage:

- the Pseudo modifier (`apply_body_theta_inertia`) leaves `iquat` NaN, which MuJoCo 4.0.0
  refuses to compile ("mass and inertia of moving bodies must be larger than mjMINVAL"):
  our modifier calls it and then sets `iquat` to the identity (the full inertia is then
  read as given);
- the stretch bounds are widened from ×[0.5, 2] to ×[0.1, 10] (the isotropic start of the
  tumbling body is more than 2× off along one axis);
- where the mass is known (the tumbling body) it is held fixed: a custom Parameter of the
  other nine coordinates;
- the measured signals' columns are mapped here (`_measured`), not by
  `TimeSeries.from_names`, which reads a ball joint as one column in MuJoCo 4.0.0.
"""

import contextlib
import io
import itertools
import re
import time

import numpy as np

STRETCH = np.array([0.1, 10.0])


def available() -> bool:
    try:
        from mujoco import sysid

        return hasattr(sysid, "optimize")
    except ImportError:
        return False


def threads() -> int:
    """The threads mujoco.sysid's residual rolls out on (its default, `n_threads`)."""
    import inspect

    from mujoco.sysid._src import residual

    return inspect.signature(residual.residual).parameters["n_threads"].default


def _parameters(case, spec, model):
    from mujoco import sysid

    theta_of = sysid.model_modifier.theta_inertia_from_body
    apply = sysid.model_modifier.apply_body_theta_inertia
    params = sysid.ParameterDict()
    for name in case.bodies:
        param = sysid.body_inertia_param(
            spec, model, name, sysid.InertiaType.Pseudo, stretch_bound_mult=STRETCH
        )
        if case.gauge == "mass":  # the mass is known: fit the other nine coordinates
            alpha = theta_of(spec, name)[0]

            def fixed_mass(s, p, name=name, alpha=alpha):
                apply(s, name, np.concatenate([[alpha], p.value]))
                s.body(name).iquat = [1.0, 0.0, 0.0, 0.0]

            param = sysid.Parameter(
                f"{name}_inertia", param.nominal[1:], param.min_value[1:], param.max_value[1:],
                modifier=fixed_mass,
            )  # fmt: skip
        else:

            def modifier(s, p, name=name):
                apply(s, name, p.value)
                s.body(name).iquat = [1.0, 0.0, 0.0, 0.0]

            param.modifier = modifier
        params.add(param)
    return params


def _signals(case, model):
    """The measured state signals' names, in the record's column order (qpos, then qvel)."""
    import mujoco

    if case.floating:
        root = model.body(1).name
        joints = [model.joint(j).name for j in range(model.njnt)
                  if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE]  # fmt: skip
        return [f"{root}_qpos", *[f"{j}_qpos" for j in joints],
                f"{root}_qvel", *[f"{j}_qvel" for j in joints]]  # fmt: skip
    joints = [model.joint(j).name for j in range(model.njnt)]
    return [f"{j}_qpos" for j in joints] + [f"{j}_qvel" for j in joints]


def _measured(times, data, model, signals):
    """The measured qpos and qvel as a `TimeSeries` of the named joint and free-body signals,
    each as wide as its joint (`TimeSeries.from_names` would do this, but in MuJoCo 4.0.0 its
    width lookup compares the joint type with enum keys and reads a ball joint as one
    column)."""
    import mujoco
    from mujoco import sysid

    widths = {mujoco.mjtJoint.mjJNT_FREE: (7, 6), mujoco.mjtJoint.mjJNT_BALL: (4, 3)}
    mapping, column = {}, 0
    for name in signals:
        base, kind = name.rsplit("_", 1)
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, base)
        if joint < 0:  # a free body, named by its body
            joint = model.body_jntadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base)]
        qpos, qvel = widths.get(mujoco.mjtJoint(int(model.jnt_type[joint])), (1, 1))
        width = qpos if kind == "qpos" else qvel
        signal = sysid.SignalType.MjStateQPos if kind == "qpos" else sysid.SignalType.MjStateQVel
        mapping[name] = (signal, np.arange(column, column + width))
        column += width
    return sysid.TimeSeries(times=times, data=data, signal_mapping=mapping)


def _sequences(case, record, spec, model, segments: int):
    """The record as mujoco.sysid's sequences: the whole record (single shooting) or
    `segments` consecutive pieces, each rolled out from its measured first state (its
    multiple-shooting option), times counted from each piece's start. The controls are
    what each MuJoCo step held (`records.held_torques`); mujoco.sysid resamples them onto
    its steps, which they already are."""
    from mujoco import sysid

    n = len(record.ts)
    bounds = np.linspace(0, n - 1, segments + 1).round().astype(int)
    signals = _signals(case, model)
    initial, control, measured, names = [], [], [], []
    for k, (first, last) in enumerate(itertools.pairwise(bounds)):
        t0, t1 = record.ts[first], record.ts[last]
        steps = (record.step_ts >= t0 - 1e-9) & (record.step_ts <= t1 + 1e-9)
        control.append(sysid.TimeSeries.from_control_names(
            record.step_ts[steps] - t0,
            record.step_torques[steps].reshape(int(steps.sum()), -1), model,
        ))  # fmt: skip
        rows = slice(first, last + 1)
        measured.append(_measured(
            record.ts[rows] - t0, np.hstack([record.qpos[rows], record.qvel[rows]]), model,
            signals,
        ))  # fmt: skip
        initial.append(sysid.create_initial_state(model, record.qpos[first], record.qvel[first]))
        names.append(f"record_{k}")
    with contextlib.redirect_stderr(io.StringIO()):  # the missing-sensors warning
        return sysid.ModelSequences(
            case.name, spec, names, initial, control, measured, allow_missing_sensors=True
        )


def _problem(case, record, spec, segments: int):
    """mujoco.sysid's parameters (at `spec`'s values) and residual function for the record,
    with a count of its rollouts."""
    from mujoco import sysid

    model = spec.compile()
    params = _parameters(case, spec, model)
    sequences = _sequences(case, record, spec, model, segments)
    residual_fn = sysid.build_residual_fn(models_sequences=[sequences])
    rollouts = [0]

    def counted(x, p, **kwargs):
        rollouts[0] += 1 if np.ndim(x) == 1 else np.shape(x)[1]
        return residual_fn(x, p, **kwargs)

    return params, counted, rollouts


def cost_at(case, record, spec, segments: int) -> float:
    """mujoco.sysid's cost ½‖r‖² at `spec`'s own parameters (the truth's, for the check
    that it poses the problem that made the record)."""
    params, residual_fn, _ = _problem(case, record, spec, segments)
    residuals, _, _ = residual_fn(params.as_vector(), params)
    r = np.concatenate(residuals)
    return 0.5 * float(r @ r)


def fit(case, record, nominal_spec, max_iters, segments: int = 1):
    """Fit the record with mujoco.sysid from `nominal_spec`, by single shooting
    (`segments = 1`) or over `segments` pieces. Returns a dict: the fitted model, seconds,
    rollouts, iterations, status, and the confidence intervals."""
    from mujoco import sysid

    begin = time.perf_counter()
    spec = nominal_spec
    params, counted, rollouts = _problem(case, record, spec, segments)
    x0 = params.as_vector()
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        fitted, result = sysid.optimize(
            params, counted, optimizer="mujoco", verbose=False, max_iters=max_iters
        )
        residuals, _, _ = counted(result.x, fitted)
    _, half_widths = sysid.calculate_intervals(residuals, result.jac)
    seconds = time.perf_counter() - begin
    final = re.search(r"Terminated after (\d+) iterations: ([^y]*?)\s*y:", printed.getvalue())
    iterations, status = (int(final.group(1)), final.group(2).strip()) if final else (None, "?")
    lo, hi = params.get_bounds()
    infinite = ~np.isfinite(half_widths)
    wide = infinite | (2 * half_widths > hi - lo)
    labels = params.get_non_frozen_parameter_names()
    at_bound = np.isclose(result.x, lo, rtol=0, atol=1e-9) | np.isclose(
        result.x, hi, rtol=0, atol=1e-9
    )
    final_model = sysid.apply_param_modifiers(fitted, spec)
    r = np.concatenate(residuals)
    return {
        "model": final_model,
        "seconds": seconds,
        "rollouts": rollouts[0],
        "iterations": iterations,
        "status": status,
        "converged": status not in ("maximum iterations reached.", "?"),
        "cost": 0.5 * float(r @ r),
        "start": x0.tolist(),
        "x": np.asarray(result.x).tolist(),
        "half_widths": [float(h) for h in half_widths],
        "infinite_intervals": int(infinite.sum()),
        "intervals_wider_than_bounds": int(wide.sum()),
        "undetermined": [lab for lab, w in zip(labels, wide, strict=True) if w],
        "at_bounds": [lab for lab, b in zip(labels, at_bound, strict=True) if b],
    }
