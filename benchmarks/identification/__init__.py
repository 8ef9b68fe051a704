"""Identification against mujoco.sysid, on the same MuJoCo-generated data sets (issue 32).

Data sets (`cases`, `records`): a floating three-body chain driven at its hinges, a
two-link arm on a welded base under gravity, a torque-free tumbling body with known mass,
and the generated family (`family`: floating trees of 2–8 bodies and arms of 2–6 links,
written from seeds, none tuned for; `--family N` runs N of each kind, default 3);
MuJoCo records each (RK4, 0.2 ms, 100 Hz) with Gaussian noise of 0, 0.1 % and 1 % of each
channel's spread, for several seeds. Both methods get the same noisy record and torque
log and start from the same nominal inertias (20-25 % off; the tumbling body from an
isotropic inertia).

Per fit, for each method:

- **parameter error**: per body ‖P̂ − P‖_F / ‖P‖_F of the pseudo-inertia, after projecting
  out the directions no method can determine (mass on a hinge's axis line shared by its two
  bodies, what a fixed shoulder axis hides, the scale of a torque-free body's inertia),
  built from the geometry; both fitted models are read back as MuJoCo models;
- **held-out prediction**: MuJoCo simulates each fitted model along a motion neither fit saw
  (new start, new torques); RMS error per channel group over its spread, in units of the
  noise level (relative when the noise is 0);
- **time to fit** (wall), bundledyn's with JAX's compilation apart: its first fit of a data
  set includes compiling (reported on its own), every later fit reuses the compiled
  evaluation; the two methods are timed in alternation (each fit pair in turn, the order
  swapped every other pair) so both see the same machine load;
- **rollouts**: mujoco.sysid's simulations (each finite-difference column is one);
  bundledyn's evaluations (residuals with exact Jacobian) and trials (residuals), each a
  solve of all shooting windows;
- **what each reports as undetermined**: bundledyn's `identifiability.undetermined`;
  mujoco.sysid's parameters whose 95 % interval (`calculate_intervals`) is infinite or wider
  than its box.

Usage, from the repository root::

    python -m benchmarks.identification                # writes results/identification.{json,md}
    python -m benchmarks.identification --quick        # the tumbling body, one seed, to a temp dir
    python -m benchmarks.identification --report-only  # redraw the markdown from the JSON
    python -m benchmarks.identification --part --cases tree0,arm1  # a case per results file
    python -m benchmarks.identification --merge        # the parts into results/identification

The whole family takes hours on two cores: `--part` keeps each case in
`results/identification_parts/` as it finishes and skips cases whose part measured this
code, so a run can be spread over sittings; `--merge` writes the report once every part
measured the same code (`parts.py`).
"""

from benchmarks.identification.cli import main

__all__ = ["main"]
