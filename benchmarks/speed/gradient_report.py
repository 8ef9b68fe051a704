"""Part 5 of `speed.md`: the gradient against the forward solve, its memory, the baselines
and where its time goes."""

from benchmarks._report import fmt


def gradient_lines(report):
    """Part 5's markdown."""
    chain, g, m = report["chain"], report["gradient"], report["memory"]
    # Results written before 2026-11-26 differentiated with diffrax's adjoint only.
    adjoint = g.get("adjoint", "RecursiveCheckpointAdjoint")
    lines = [
        "",
        "## 5. Gradients",
        "",
        f"- `jax.grad` of a loss on the {chain['t1']:g} s rollout ({adjoint}, `simulate`'s "
        f"default): {fmt(g['grad'], 1e3)} ms against {fmt(g['forward'], 1e3)} ms forward, "
        f"ratio {g['ratio']:.2f} (of the medians; of the minima "
        f"{g['grad']['min'] / g['forward']['min']:.2f}, less moved by the host's phases).",
        *checkpointed_lines(g),
        f"- {m['steps']} RKMK4 steps ({m.get('adjoint', 'RecursiveCheckpointAdjoint')}), "
        "gradient through all of them: peak memory of the whole "
        f"process {m['peak_rss_bytes'] / 1e9:.2f} GB ({m['rss_before_bytes'] / 1e9:.2f} GB "
        "before compiling the gradient: imports and JAX's runtime), XLA temporary buffers "
        f"{(m['xla_temp_bytes'] or 0) / 1e6:.2f} MB, {m['seconds']:.1f} s, gradient finite: "
        f"{m['grad_finite']}.",
    ]
    return lines + baseline_lines(g) + gradient_profile_lines(report)


def checkpointed_lines(g):
    """The same gradient with diffrax's `RecursiveCheckpointAdjoint`, where it was timed."""
    if "grad_checkpointed" not in g:
        return []
    c = g["grad_checkpointed"]
    return [
        f"- The same with diffrax's `RecursiveCheckpointAdjoint`, timed in alternation: "
        f"{fmt(c, 1e3)} ms, ratio {c['median'] / g['forward']['median']:.2f}."
    ]


def baseline_lines(g):
    """Part 5a's baselines in markdown (none in results written before 2026-11-24 10:00)."""
    if "baselines" not in g:
        return []
    rows = []
    for depth, b in g["baselines"].items():
        ratio = b["grad"]["median"] / b["forward"]["median"]
        what = "linear, $L = 1$" if depth == "1" else f"$L = {depth}$"
        rows.append(
            f"| {what} | {fmt(b['field'], 1e6)} | {b['field_vjp']['median'] / b['field']['median']:.1f} "
            f"| {fmt(b['forward'], 1e3)} | {fmt(b['grad'], 1e3)} | {ratio:.2f} "
            f"| {b['grad']['min'] / b['forward']['min']:.2f} |"
        )
    return [
        "",
        "Baselines, timed in alternation with the two above: diffrax's own `Dopri8` over the "
        "same time at the same tolerance on $\\dot y = K_L\\tanh(K_{L-1}\\cdots\\tanh(K_1 y))$, "
        "$K_l$ fixed skew 30×30 matrices (`skew_network_ode`), whose VJP costs little more "
        "than the field: what diffrax's adjoint loop costs with a cheap reverse pass.",
        "",
        "| field | evaluation [µs] | VJP / evaluation | forward [ms] | `jax.grad` [ms] "
        "| ratio | ratio of the minima |",
        "|---|--:|--:|--:|--:|--:|--:|",
        *rows,
    ]


def gradient_profile_lines(report):
    """Part 5c's markdown: the units' costs and the gradient of part 5a accounted by them."""
    g = report["gradient"]
    p = g["profile"]
    med = {k: p[k]["median"] for k in ("field", "field_vjp", "step", "step_vjp")}
    forward, grad = g["forward"]["median"], g["grad"]["median"]
    steps, vjps = p["steps"], p["steps"] * med["step_vjp"]
    rest = (
        ": the rest is the adjoint's own, recording the steps in the forward solve (in "
        "buffers as long as `max_steps`) and its sweep's bookkeeping"
        if forward + vjps < grad
        else " (alone, a step's VJP costs more than inside the solve)"
    )
    return [
        "",
        "### Where the gradient's time goes",
        "",
        "Per call in a compiled loop, 5-body chain [µs], timed in alternation with the "
        f"gradient above; the step is `RKMK87`'s ({p['stages']} field evaluations) at the "
        "forward solve's mean step.",
        "",
        "| unit | evaluation | VJP | VJP / evaluation |",
        "|---|--:|--:|--:|",
        # Results before 2026-11-24 timed `Scene.vector_field` and do not name the unit.
        f"| {p.get('field_unit', 'vector field')} | {fmt(p['field'], 1e6)} "
        f"| {fmt(p['field_vjp'], 1e6)} "
        f"| {med['field_vjp'] / med['field']:.1f} |",
        f"| RKMK87 step | {fmt(p['step'], 1e6)} | {fmt(p['step_vjp'], 1e6)} "
        f"| {med['step_vjp'] / med['step']:.1f} |",
        "",
        f"The forward solve takes {steps} steps (accepted and rejected): at the loop's cost "
        f"per step {steps * med['step'] * 1e3:.1f} ms, against {forward * 1e3:.1f} ms "
        f"measured. The forward solve and {steps} step VJPs ({vjps * 1e3:.0f} ms) account for "
        f"{(forward + vjps) / grad:.0%} of the gradient's {grad * 1e3:.0f} ms{rest}. "
        "A step's VJP runs the step's stage maps forward again from its stored start, with "
        "the field's values at the stages kept by the forward solve (the field is not "
        "evaluated again), and transposes it. A gradient within 4× of the forward solve would "
        f"need the {steps} step VJPs within three forward solves, each within "
        f"{3 * forward / (steps * med['step']):.1f}× the step; it costs "
        f"{med['step_vjp'] / med['step']:.1f}×, of which the {p['stages']} stages' field VJPs "
        f"(each {med['field_vjp'] / med['field']:.1f}× the field, its written-out pass alone) take "
        f"{p['stages'] * med['field_vjp'] / med['step_vjp']:.0%}.",
    ]
