"""What the benchmark measures for one problem (`disc` or `bicycle`): the time to the first
answer on both sides, cold; then, member by member, the time per simulated second timed in
alternation and the agreement of the two trajectories."""

import time

import numpy as np

from benchmarks._timing import interleaved, summary
from benchmarks.nonholonomic import peer

RTOL = 1e-10  # both sides' rtol = atol, timed
TIGHT = 1e-12  # the agreement once more, each side ten times more accurate


def _cold():
    """Forget what earlier rounds derived and compiled."""
    import jax
    from sympy.core.cache import clear_cache

    clear_cache()
    jax.clear_caches()


def _peer_first_answer(problem, variant, x0, ts):
    """sympy from the description to the trajectory from `x0`: `(derive s, lambdify s,
    first solve s)`."""
    start = time.perf_counter()
    model = problem.kane_model(variant)
    peer.derive_equations(model)
    derived = time.perf_counter()
    field = peer.numeric_field(model)
    lambdified = time.perf_counter()
    peer.integrate(field, x0, ts, RTOL)
    return derived - start, lambdified - derived, time.perf_counter() - lambdified


def _ours_first_answer(problem, variant, y0, ts):
    """bundledyn from the description to the trajectory from `y0`: building the model,
    tracing, compiling and running the solve."""
    start = time.perf_counter()
    np.asarray(problem.simulate(problem.ours_model(variant), y0, ts, RTOL))
    return time.perf_counter() - start


def model_sides(problem, variant):
    """`(bundledyn's model, the peer's numeric field, its dependent speeds)` of a variant,
    derived once for the untimed work (initial states, the member runs)."""
    model = problem.kane_model(variant)
    return problem.ours_model(variant), peer.numeric_field(model), peer.dependent_speeds(model)


def first_answers(problem, member, sides, ts, repeats):
    """Cold times to the first trajectory of `member`, `repeats` rounds of both sides;
    `sides` (`model_sides`) give the initial states."""
    ours, _, speeds = sides
    y0, x0 = problem.initial_states(ours, speeds, member)
    rounds = {"derive": [], "lambdify": [], "solve": [], "sympy": [], "bundledyn": []}
    for _ in range(repeats):
        _cold()
        derive, lambdify, solve = _peer_first_answer(problem, member["variant"], x0, ts)
        rounds["derive"].append(derive)
        rounds["lambdify"].append(lambdify)
        rounds["solve"].append(solve)
        rounds["sympy"].append(derive + lambdify + solve)
        _cold()
        rounds["bundledyn"].append(_ours_first_answer(problem, member["variant"], y0, ts))
    return {name: summary(samples) for name, samples in rounds.items()}


def _member_run(problem, member, sides, ts, repeats):
    """One member: both sides' seconds per simulated second, in alternation, and their
    largest difference at `RTOL` and at `TIGHT`."""
    ours, field, speeds = sides
    y0, x0 = problem.initial_states(ours, speeds, member)
    results = {}

    def run_ours(rtol=RTOL):
        results["bundledyn", rtol] = np.asarray(problem.simulate(ours, y0, ts, rtol))

    def run_peer(rtol=RTOL):
        results["sympy", rtol] = peer.integrate(field, x0, ts, rtol)

    run_ours(TIGHT), run_peer(TIGHT)
    timed = interleaved({"bundledyn": run_ours, "sympy": run_peer}, repeats)
    horizon = float(ts[-1] - ts[0])
    per_second = {
        name: {k: v / horizon for k, v in runs.items()} for name, (_, runs) in timed.items()
    }
    return {
        "label": member["label"],
        **per_second,
        "agreement": problem.disagreement(results["bundledyn", RTOL], results["sympy", RTOL]),
        "agreement_tight": problem.disagreement(
            results["bundledyn", TIGHT], results["sympy", TIGHT]
        ),
    }


def member_runs(problem, members, sides, ts, repeats):
    """`_member_run` of every member; `sides` maps each model variant to its `model_sides`."""
    out = []
    for member in members:
        out.append(_member_run(problem, member, sides[member["variant"]], ts, repeats))
        print(f"  {member['label']}: agree {out[-1]['agreement']:.1e}", flush=True)
    return out
