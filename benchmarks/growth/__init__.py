"""How the field's cost grows with the bodies, from 10 to 150, against MuJoCo's.

The family (`benchmarks/family`) stops at 20 bodies and the survey (`benchmarks/survey`) at
the published models; this benchmark draws random free-floating trees of 10, 20, 40, 80
and 150 bodies (`members.py`: hinges, or a mix of hinges, ball joints and hinge pairs; each
body hung from one of the two before it, so the trees are nearly as deep as they are
long: the recursions' worst case), several seeds per size, gravity off. Per member, after
checking its metric against MuJoCo's mass matrix and its recursive field against the
dense one (values and VJPs), timed in alternation in one process on one core:

1. one evaluation of the field with the scene's default algorithm (the articulated-body
   recursions), with the dense one, and MuJoCo's `mj_forward` at the same state;
2. the field's VJP as `simulate`'s default adjoint takes it (`ReplayedSceneTerm`);
3. on members up to `GRADIENT_MOST_DOFS` degrees of freedom, `jax.grad` of the survey's
   loss over the forward solve (`benchmarks/survey/gradient.py`).

The report fits each time's growth in the number of bodies, log–log over every member of a
kind (the exponent: 1 is linear), beside each target of the issue.
"""
