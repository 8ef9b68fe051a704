"""The mujoco.sysid side of the identification benchmark (MuJoCo ≥ 3.4's `mujoco.sysid`).

Its documented path, on the same noisy records as bundledyn: each fitted body an
`InertiaType.Pseudo` parameter (the same log-Cholesky coordinates of the pseudo-inertia),
the nominal MJCF (same start), the measured qpos and qvel as state signals, the torque log
as controls, `build_residual_fn` (single shooting with MuJoCo's rollout, residuals scaled
per channel by the measured data's magnitude) and `optimize(optimizer="mujoco")`
(`mujoco.minimize.least_squares`, finite-difference Jacobians), then
`calculate_intervals` at the optimum.

Three departures from the defaults, each needed or to its advantage:

- the Pseudo modifier (`apply_body_theta_inertia`) leaves `iquat` NaN, which MuJoCo 4.0.0
  refuses to compile ("mass and inertia of moving bodies must be larger than mjMINVAL"):
  our modifier calls it and then sets `iquat` to the identity (the full inertia is then
  read as given);
- the stretch bounds are widened from ×[0.5, 2] to ×[0.1, 10] (the isotropic start of the
  tumbling body is more than 2× off along one axis);
- where the mass is known (the tumbling body) it is held fixed: a custom Parameter of the
  other nine coordinates.
"""

import contextlib
import io
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


def fit(case, record, nominal_spec, max_iters):
    """Fit the record with mujoco.sysid from `nominal_spec`. Returns a dict: the fitted
    model, seconds, rollouts, iterations, status, and the confidence intervals."""
    from mujoco import sysid

    begin = time.perf_counter()
    spec = nominal_spec
    model = spec.compile()
    params = _parameters(case, spec, model)
    x0 = params.as_vector()
    ts = record.ts
    inside = record.torque_ts <= ts[-1] + 1e-9  # the torque log over the record
    control = sysid.TimeSeries.from_control_names(
        record.torque_ts[inside], record.torques[inside].reshape(int(inside.sum()), -1), model
    )
    measured = sysid.TimeSeries.from_names(
        ts, np.hstack([record.qpos, record.qvel]), model, names=_signals(case, model)
    )
    initial = sysid.create_initial_state(model, record.qpos[0], record.qvel[0])
    with contextlib.redirect_stderr(io.StringIO()):  # the missing-sensors warning
        sequences = sysid.ModelSequences(
            case.name, spec, "record", initial, control, measured, allow_missing_sensors=True
        )
    residual_fn = sysid.build_residual_fn(models_sequences=[sequences])
    rollouts = [0]

    def counted(x, p, **kwargs):
        rollouts[0] += 1 if np.ndim(x) == 1 else np.shape(x)[1]
        return residual_fn(x, p, **kwargs)

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
