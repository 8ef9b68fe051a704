"""`python -m benchmarks.nonholonomic`: rolling bodies against sympy.physics.mechanics.

The same problems given to both: the leaning rolling disc (a rigid body rolling on a
plane, two nonholonomic constraints) and the Whipple bicycle with the benchmark parameters
of Meijaard et al. (2007) (four bodies, two rolling wheels, the front wheel's contact
carried in differentiated form), the bicycle twice on bundledyn's side. The peer is what a sympy user runs: `KanesMethod` with
the velocity constraints and dependent speeds, its `mass_matrix_full` and `forcing_full`
made numeric by `lambdify` (with common subexpressions) and integrated by scipy's `DOP853`.
bundledyn runs its own models: the disc as a `RigidBody` in a `RollingMode` (`simulate`,
`RKMK87`), the bicycle as `WhippleBicycle` (`NonholonomicTerm`, Maggi's equations by
autodiff, diffrax's `Dopri8`) and as a tree on two rolling wheels (the shipped scene
`bicycle.toml`: `RollingWheelMode`, the rear frame's pose on SE(3), `simulate`'s `RKMK87`).

For each problem, over a family of initial states (random seeds at several energies; two
mass distributions of the disc, several forward speeds of the bicycle):

- **time to the first answer**: from the model's description to the first trajectory.
  sympy: deriving the equations, `lambdify` and the first solve; bundledyn: building the
  model, tracing and compiling the solve and running it. Measured cold (sympy's cache and
  JAX's compiled programs cleared, no on-disk compilation cache), several times.
- **time per simulated second** at rtol = atol = 1e-10: each side's solve of the same
  member, timed in alternation (`_timing.interleaved`).
- **agreement**: the largest difference between the two trajectories at the saved times
  (the disc's orientation matrix and centre; the bicycle's yaw, roll, pitch and steer and
  the roll and steer rates), at rtol 1e-10 and at 1e-12.

`--quick` runs one member of each problem over a short horizon.
"""
