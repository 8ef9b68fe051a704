"""The float32 half of the float32 case, run as its own process: JAX's default precision,
as a user who never called `enable_x64()` has it (switching precision inside one process
reuses traces of the other). The system arrives pickled, its arrays as NumPy arrays."""

import json
import pickle
import sys
import warnings


def main(path: str) -> None:
    """Print, as JSON, a float32 solve's final pose and shape, the refusal of rtol 1e-12, and
    the invariance check's worst residual and tolerance, for the system pickled at `path`."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from .._checks._report import galilean_invariance
    from .._scene import Scene
    from .._simulate import simulate
    from ._start import start_of

    with open(path, "rb") as file:
        system = pickle.load(file)
    system = jax.tree_util.tree_map(
        lambda x: jnp.asarray(x, jnp.float32) if isinstance(x, np.ndarray) and x.dtype.kind == "f"
        else x, system,
    )  # fmt: skip
    system, state = start_of(system)
    traj = simulate(Scene(system), state, 1.0, rtol=1e-5, atol=1e-5)
    try:
        simulate(Scene(system), state, 1.0, rtol=1e-12, atol=1e-12)
        refusal = ""
    except ValueError as error:
        refusal = str(error)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = galilean_invariance(system, jax.random.key(0), n=64)
    final = jnp.concatenate([traj.g[-1, :3].ravel(), traj.q[-1]])
    print(json.dumps({
        "dtype": str(final.dtype), "final": [float(v) for v in final], "refusal": refusal,
        "invariance": float(report.worst.max()), "tolerance": report.tolerance,
    }))  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1])
