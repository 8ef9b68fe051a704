"""What uniform gravity costs in the field, over the family of models and larger trees.

Each member is one of the family's random trees (`benchmarks/family/members.py`), three
larger random trees of mixed joints (35, 50 and 70 bodies: 65, 115 and 140 degrees of
freedom) and gymnasium's humanoid, each at a tumbling start. Timed in alternation, per
evaluation inside a compiled loop: the scene's field without effects, with `bd.Gravity`,
with the same gravity's forces by autodiff of its potential (the general `AbstractPotential`
rule, what `Gravity` did before it wrote its forces out), and with the Earth's
`bd.GravityGradient` (its forces written out too); the body field's VJP as `simulate`'s
default adjoint takes it, without effects and with either uniform gravity; and MuJoCo's
`mj_forward` of the same model with its gravity on.
"""
