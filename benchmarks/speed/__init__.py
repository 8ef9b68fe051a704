"""Speed against MuJoCo, measured in one run on the same MJCF model.

Systems: free-floating chains of n boxes joined by hinges with alternating axes, no gravity
and no forces, written once as MJCF (`benchmarks/_models.py: chain_mjcf`) and loaded by
both MuJoCo and bundledyn (`bd.Multibody.from_mjcf`). float64 on the CPU. Every time is
the median, min and max over `--repeats` runs (≥ 5 for the published results).

1. **Vector field** (`field`): one evaluation of the scene's field (`bd.SceneTerm.vf`)
   inside a compiled `fori_loop` (no dispatch), against MuJoCo's `mj_forward` (Python loop
   over the C call) and one RK4 step (`mujoco.rollout`, a C loop), for n = 1, 5, 10, 20.
2. **10 s of the 5-body chain** (`chain`): bundledyn's default solver (RKMK87) and its
   fifth-order RKMK54 swept over tolerances, RKMK87 with fixed steps
   (`diffrax.ConstantStepSize`) over the step, and MuJoCo RK4 over time steps, errors
   against a reference (RKMK87 at rtol 1e-13, checked against diffrax's Dopri8); wall time
   interpolated (log–log) at the error of MuJoCo RK4 with dt = 1e-2 and at 1e-10.
3. **Batches** (`batch`, `mujoco_batch`): `jax.vmap` of 1 s rollouts over 1024 initial
   states, each method at the loosest tolerance (1, 2, 5 per decade) or longest step whose
   largest error over 16 rollouts of the batch is at most MuJoCo RK4's with dt = 1e-2 on
   them, against `mujoco.rollout` on 2 threads and, when `mujoco.mjx` is installed, MJX:
   timed at dt = 1e-2 and compared at the step where its error on those rollouts is
   MuJoCo's.
4. **Compile times** (`compile`) of `simulate` (n = 5, 20) and of its `jax.grad` (n = 20).
5. **Gradients** (`gradient`): `jax.grad` of a loss on the 10 s rollout over the forward
   solve, timed in alternation with a profile of where its time goes (the field, a step
   and their VJPs) and with baselines, diffrax's `Dopri8` on fields of the same size whose
   VJP is cheap (a linear one, and a network about as costly as the chain's field); peak
   memory of the gradient of a 10⁵-step rollout (RKMK4, fixed step, checkpointed).

Parts 1, 3 and 4 run twice, in fresh worker processes: with XLA's defaults and with
`bundledyn.CPU_XLA_FLAGS` (XLA reads its flags when the backend starts).

Every comparison is timed in alternation (`benchmarks/_timing.py: interleaved`): each
repeat runs bundledyn and MuJoCo once each, in turn, so that both see the same load. On a
shared machine whole seconds run 1.5–2× slower, pinned to one core or not; timed one after
the other, the two sides of a ratio could fall in different phases.

Usage, from the repository root (needs the `bench` extra for MuJoCo)::

    python -m benchmarks.speed                 # full run; writes results/speed.{md,json}
    python -m benchmarks.speed --quick         # small sizes, 2 repeats, to a temporary folder
    python -m benchmarks.speed --report-only   # redraw the markdown from the JSON
    python -m benchmarks.speed --device-batch  # part 3 on a GPU: results/speed_gpu.{md,json}

`--device-batch` runs on JAX's default device at the settings of the committed CPU run,
with MuJoCo on the host's CPU, for 1024 to 65536 rollouts, and reruns the first 64 on the
host's CPU to show that the device computes the same trajectories.
"""

from benchmarks.speed.cli import main

__all__ = ["main"]
