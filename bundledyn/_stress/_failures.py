"""Cases where the right answer is a clear refusal: impossible tolerances, float32 limits,
non-finite forces, singular metrics, exhausted step budgets."""

import json
import pathlib
import pickle
import subprocess
import sys
import tempfile
import warnings

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._effects import ShapeForce
from .._precision import LIBRARY_FOLDERS
from .._scene import Scene
from .._simulate import simulate
from .._state import State
from .._systems._generic import GenericSystem
from ._models import chain
from ._row import StressRow
from ._start import XI0, start_of

STATE = dict(q=(0.3, -0.5), xi=XI0, qdot=(1.0, -2.0))


def _raises(case, shows, run, error, *words) -> StressRow:
    """A row that passes (0) when `run()` raises `error` with each of `words` in its message
    and fails (1) otherwise, naming what happened instead."""
    try:
        run()
    except error as caught:
        message = str(caught)
        missing = [w for w in words if w not in message]
        if not missing:
            return StressRow(case, shows, 0.0, 0.0)
        return StressRow(case, shows, 1.0, 0.0, f"the message lacks {missing}: {message[:200]}")
    return StressRow(case, shows, 1.0, 0.0, f"no {error.__name__} was raised")


def _float32_process(system) -> dict:
    """What `_float32.main` prints for `system`, run as its own process."""
    arrays = jax.tree_util.tree_map(lambda x: np.asarray(x) if eqx.is_array(x) else x, system)
    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / "system.pickle"
        path.write_bytes(pickle.dumps(arrays))
        command = [sys.executable, "-m", "bundledyn._stress._float32", str(path)]
        done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the float32 run failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def float32(system=None) -> tuple[StressRow, ...]:
    r"""The model in float32 (JAX's default, no `enable_x64()`): a solve at rtol 1e-5 against
    the float64 solve at 1e-12 from the same start, rtol 1e-12 refused with the advice to
    use float64, and the invariance check passing at its float32 tolerance.

    Guards against jaxsim (float32 NaN after 18 s), tolerances silently not met, and an
    invariance check that failed valid float32 models by rounding alone.

    **Arguments:**

    - `system`: the model (picklable: a `GenericSystem`'s function must be importable);
      default the cases' three-link chain.

    **Returns:**

    Rows: the float32 final pose and shape error relative to their size (bound 1e-4), the
    refusal, the invariance residual.
    """
    system, state = start_of(system)
    reference = simulate(Scene(system), state, 1.0, rtol=1e-12, atol=1e-12)
    run = _float32_process(system)
    expected = np.concatenate(
        [np.asarray(reference.g[-1, :3]).ravel(), np.asarray(reference.q[-1])]
    )
    got = np.asarray(run["final"])
    error = np.abs(got - expected).max() / np.abs(expected).max()
    refused = "enable_x64" in run["refusal"]
    return (
        StressRow("float32", "float32 at rtol 1e-5 vs float64, final pose and shape (1 s)",
                  float(error) if run["dtype"] == "float32" else np.nan, 1e-4,
                  "" if run["dtype"] == "float32" else f"ran in {run['dtype']}"),
        StressRow("float32", "float32 at rtol 1e-12 is refused, pointing to enable_x64",
                  0.0 if refused else 1.0, 0.0, "" if refused else f"got: {run['refusal']!r}"),
        StressRow("float32", "invariance residual in float32 (default tolerance)",
                  run["invariance"], run["tolerance"]),
    )  # fmt: skip


def advice() -> tuple[StressRow, ...]:
    """Tolerances no solve can meet are refused in one line that says what would help.

    Guards against advice that cannot help (`enable_x64()` when it is on, `max_steps` for a
    tolerance below rounding) and warnings that point into the library instead of the
    caller's line.
    """
    system, state = chain((1.0, 1.5)), State(jnp.eye(4), q=(0.3,), xi=STATE["xi"], qdot=(1.0,))
    scene = Scene(system)
    rows = [
        _raises("advice", "rtol = 1e-20 in float64: refused, says float64 is the widest",
                lambda: simulate(scene, state, 1.0, rtol=1e-20, atol=1e-20), ValueError,
                "float64", "1e-14"),
        _raises("advice", "a negative rtol is refused",
                lambda: simulate(scene, state, 1.0, rtol=-1.0), ValueError, "non-negative"),
    ]  # fmt: skip
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulate(scene, state, 0.1, rtol=1e-15, atol=1e-15)
    files = [w.filename for w in caught if "rounding error" in str(w.message)]
    # This module is the library's too: the warning lands in whoever called the battery.
    at_caller = len(files) == 1 and not files[0].startswith(LIBRARY_FOLDERS)
    rows.append(
        StressRow("advice", "a tolerance near rounding warns at the caller's line",
                  0.0 if at_caller else 1.0, 0.0, "" if at_caller else f"warned at {files}")
    )  # fmt: skip
    return tuple(rows)


def bad_values() -> tuple[StressRow, ...]:
    """A force that returns NaN, a metric that becomes singular, a step budget run out:
    each stops the solve with a message naming it, never a silent wrong answer.

    Guards against the NaN trajectories that MJX and jaxsim return without a word, and
    against a rejected-step loop that ends in a misleading "increase max_steps".
    """
    system = chain((1.0, 1.5, 2.0))
    state = State(jnp.eye(4), **STATE)
    nan_after = ShapeForce(lambda t, q, qdot: jnp.where(t > 0.3, jnp.nan, 0.0) * qdot)

    def degenerate(q, qdot, xi):  # the shape's inertia vanishes at q = 1
        return 0.5 * (xi @ xi + (1.0 - q[0]) * qdot[0] ** 2)

    flat, flat_state = GenericSystem(degenerate, 1), State(jnp.eye(4), q=(0.0,), qdot=(1.0,))
    return (
        _raises("bad_values", "a force returning NaN at t > 0.3 stops the solve, named",
                lambda: simulate(Scene(system, [nan_after]), state, 1.0), Exception,
                "step size fell to the rounding error", "NaN or Inf"),
        _raises("bad_values", "a metric singular at q = 1 stops the solve, named",
                lambda: simulate(Scene(flat), flat_state, 2.0), Exception,
                "step size fell to the rounding error", "metric becoming singular"),
        StressRow("bad_values", "max_steps reached is diffrax's result, not a wrong answer",
                  float(simulate(Scene(system), state, 10.0, max_steps=4, throw=False).result
                        != diffrax.RESULTS.max_steps_reached), 0.0),
    )  # fmt: skip
