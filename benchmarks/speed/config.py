"""The speed benchmark's settings, and bundledyn's methods in parts 2 and 3."""

import bundledyn as bd

T_CHAIN = 10.0
MUJOCO_DT = 1e-2
TARGET_ERROR = 1e-10
LOOP_EVALS = 1000
BATCH = 1024
MEMORY_STEPS = 100_000
DEVICE_BATCHES = (1024, 8192, 65536)  # `--device-batch`
BASELINE_DEPTHS = (1, 32)  # part 5a: the linear ODE and a network about as costly as the chain
FIXED_STEPS = (40, 50, 60, 70, 80, 100, 120, 160, 200, 250)  # steps over 10 s, part 2
# bundledyn's methods in parts 2 and 3, the first the default: name -> (solver, step control).
# Adaptive ones are swept over rtol, fixed-step ones over the step.
METHODS = {
    "RKMK87": ("RKMK87", "adaptive"),
    "RKMK54": ("RKMK54", "adaptive"),
    "RKMK87, fixed step": ("RKMK87", "fixed"),
}
# Parts 1, 3 and 4 run under each: the key of `report["settings"]` -> its label.
XLA_SETTINGS = {"bundledyn": "CPU_XLA_FLAGS", "xla_defaults": "XLA defaults"}
# The packages whose versions a report names.
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "numpy", "mujoco", "mujoco-mjx")


def simulate_options(solver, control, setting):
    """`bd.simulate`'s keywords for `solver` (a name in bundledyn or diffrax) at `setting`:
    rtol (atol = rtol / 100) for `control = "adaptive"`, the step for `"fixed"`."""
    import diffrax

    options = {"solver": (getattr(bd, solver, None) or getattr(diffrax, solver))()}
    if control == "fixed":
        return options | {"dt0": setting, "stepsize_controller": diffrax.ConstantStepSize()}
    return options | {"rtol": setting, "atol": setting * 1e-2}


def rollout_fn(scene, t1, solver, control="adaptive"):
    """A jitted `(state, setting) -> (final state, steps)` of `bd.simulate` (see
    `simulate_options`); the setting is traced, so a sweep compiles once."""
    import jax

    from benchmarks._errors import final_state

    @jax.jit
    def run(state, setting):
        options = simulate_options(solver, control, setting)
        traj = bd.simulate(scene, state, t1, max_steps=200_000, **options)
        return final_state(traj), traj.stats["num_steps"]

    return run


def setting_label(method, setting):
    """`rtol 1e-07` for an adaptive method of `METHODS`, else (fixed step, MuJoCo) `dt 0.167`."""
    adaptive = METHODS.get(method, (None, "fixed"))[1] == "adaptive"
    return f"rtol {setting:.0e}" if adaptive else f"dt {setting:.3g}"
