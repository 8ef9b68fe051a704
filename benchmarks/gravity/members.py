"""The members: the family's structures and larger random trees, each at one tumbling start."""

from benchmarks.family.members import HUMANOID, RATES, STRUCTURES, Member, random_tree

LARGE = ((35, "mixed"), (50, "mixed"), (70, "mixed"))  # 65, 115 and 140 DoF


def members(quick: bool) -> list[Member]:
    """Every family structure and the larger trees at the low energy, and the humanoid (the
    quick run: the family's first structure alone)."""
    structures = STRUCTURES[:1] if quick else STRUCTURES + LARGE
    rate = RATES["low"]
    out = [
        Member(f"tree {seed}: {bodies} {kind}", random_tree(bodies, kind, seed), bodies, kind, rate)
        for seed, (bodies, kind) in enumerate(structures)
    ]
    if not quick:
        out.append(Member("humanoid", HUMANOID.read_text(), 13, "hinge", rate))
    return out
