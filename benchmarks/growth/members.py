"""The members: random free-floating trees of 10 to 150 bodies, several seeds per size."""

from benchmarks.family.members import RATES, Member, random_tree

SIZES = (10, 20, 40, 80, 150)  # bodies
KINDS = ("hinge", "mixed")
SEEDS = 2  # per kind and size
FIRST_SEED = 500  # apart from the family's and the gravity benchmark's trees


def members(quick: bool) -> list[Member]:
    """Every kind and size, `SEEDS` trees each, at the family's low energy (the quick run:
    one hinge tree of 10 bodies and one of 20)."""
    if quick:
        grid = [("hinge", bodies) for bodies in SIZES[:2]]
    else:
        grid = [(kind, bodies) for kind in KINDS for bodies in SIZES for _ in range(SEEDS)]
    return [
        Member(
            f"{bodies} {kind}, seed {FIRST_SEED + index}",
            random_tree(bodies, kind, FIRST_SEED + index),
            bodies,
            kind,
            RATES["low"],
        )
        for index, (kind, bodies) in enumerate(grid)
    ]
