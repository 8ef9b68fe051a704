"""What accuracy costs in time: work–precision of every solver, with peers measured in the same run.

For six scenes (`problems`: a Dzhanibekov rigid body, the free MJCF chain `chain5.xml`, an
affine body on a shape spring, the falling cat with a prescribed shape loop, a 10-body
chain in a gravity gradient, and a stiff chain whose spring is 10⁶ times stiffer than its
soft one) this benchmark sweeps every method over its tolerances (adaptive) or step sizes
(fixed), `bundledyn.simulate`'s default solver first (`sweep.default_solver`: the
library's `DEFAULT_SOLVER`, the class `simulate` integrates with), and records, for each
point (`sweep`): the error of the state at t1 against a reference solution, the energy
and momentum drift, the wall time (median, min and max of ≥ 5 runs after compilation),
the steps and vector-field evaluations, and the compile time; a fixed step too long for a scene makes its solve raise,
and the point keeps the message. Each adaptive method's time and steps per extra digit of
accuracy are fitted over its sweep's asymptotic range (`digits`), beside the $10^{1/p}$ its
order $p$ predicts.

The reference is RKMK 5(4) at rtol 1e-13; a second reference, Dopri8 on the embedded
state at rtol 1e-13, must agree with it, and their difference is reported as the floor
below which errors mean nothing. The error of a state is the largest of
$|\\log(g_{\\rm ref}^{-1}g)|_\\infty$, $|q - q_{\\rm ref}|_\\infty$, $|\\xi - \\xi_{\\rm ref}|_\\infty$ and
$|\\dot q - \\dot q_{\\rm ref}|_\\infty$ (`benchmarks/_errors.py: state_error`).

Peers on the chain (`peers`), when installed (extra `bench`, i.e. `mujoco` and `scipy`):
MuJoCo's RK4, Euler and implicitfast integrators on the identical MJCF model with gravity
off, run by `mujoco.rollout` in C; and scipy's `solve_ivp(DOP853)` on bundledyn's jitted
vector field as a non-JAX baseline. Throughput of vmapped batches (1, 64, 1024), the cost
of `jax.grad` of a rollout loss under two adjoints, and compile time against the number of
bodies complete the report (`extras`).

Usage, from the repository root::

    python -m benchmarks.accuracy_cost            # everything; writes benchmarks/results/
    python -m benchmarks.accuracy_cost --quick    # one scene, a few points, to a temporary folder
    python -m benchmarks.accuracy_cost --out DIR  # write the report elsewhere
"""

from benchmarks.accuracy_cost.cli import main

__all__ = ["main"]
