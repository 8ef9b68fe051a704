"""Speed against MuJoCo over a family of models the benchmark was not tuned on.

`python -m benchmarks.speed` measures one chain in depth; this benchmark measures the
speed targets on every member of a family (`members.py`): eight random free-floating
trees drawn from seeds (5, 10 and 20 bodies; hinge, ball, composite and mixed joints;
random axes, masses, sizes and link offsets) and gymnasium's humanoid, each at two
energies, float64 on the CPU. Per member, timed in alternation in one process:

1. one evaluation of bundledyn's vector field (`bd.SceneTerm.vf` in a compiled loop)
   against MuJoCo's `mj_forward` at the same state;
2. a tumbling start solved with bundledyn's default solver (RKMK87) and with the
   lower-order RKMK54 it is chosen over (rtol 1e-2 … 1e-12, atol = rtol / 100: MuJoCo's
   dt = 1e-2 error is coarse on energetic members, and a sweep stopping short of it
   would time a solve more accurate than the target) and
   MuJoCo RK4 (`mujoco.rollout`, dt = 1e-2 … 1e-2/32), errors at t1 against a reference;
   bundledyn's time over MuJoCo's at MuJoCo's error with dt = 1e-2 and at 1e-9, each
   interpolated log–log on its sweep. t1 is the member's
   predictable horizon: the longest of 10, 5, 2, 1 and 0.5 s over which RKMK87 and
   diffrax's Dopri8, both at rtol 1e-13, agree to 1e-10 (many members are chaotic over
   10 s, where a final state's error would measure nothing);
3. over the same horizon, `jax.grad` of a loss on the rollout (default solver, rtol 1e-8)
   over the forward solve, with `simulate`'s default adjoint, diffrax's
   `RecursiveCheckpointAdjoint` and its `BacksolveAdjoint`; and the VJPs of the body field
   and of one RKMK87 step over themselves (`gradient.py`).

The report gives each target's worst case over the family beside its median, and names
the member that gave it. Parts 1–2 (`mujoco`) and 3 (`gradient`) can be measured apart
(`--only`): the run keeps the other part from the JSON already there, and records the
gradients' own provenance beside the file's.

Usage, from the repository root (needs the `bench` extra for MuJoCo)::

    python -m benchmarks.family                  # full run; writes results/family.{md,json}
    python -m benchmarks.family --only gradient  # the gradients, into results/family.json
    python -m benchmarks.family --quick          # one small model, 1 s, to a temporary folder
    python -m benchmarks.family --report-only    # redraw the markdown from the JSON
"""

from benchmarks.family.cli import main

__all__ = ["main"]
