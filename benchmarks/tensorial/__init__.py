"""Chains of Lagrange gyroscopes in tensor coordinates (issue 58): the field and a rollout in
each formulation beside the chain as a `Multibody` and MuJoCo, over a family of chains."""
