"""Markdown pieces shared by the benchmarks' reports."""


def fmt(stats, scale, digits=3):
    """A time summary as `median (min–max)`, each times `scale`, to `digits` digits."""
    return f"{stats['median'] * scale:.{digits}g} ({stats['min'] * scale:.{digits}g}–{stats['max'] * scale:.{digits}g})"


def versions(env):
    """`package version, …` of the installed packages of an environment."""
    return ", ".join(f"{k} {v}" for k, v in env["versions"].items() if v)


def provenance_lines(report, key="provenance", what="Code"):
    """The report's provenance as a markdown paragraph; none for results written before
    runs recorded it."""
    p = report.get(key)
    if not p:
        return []
    if p["commit"] is None:
        code = "outside a git checkout"
    else:
        code = f"commit `{p['commit'][:12]}`"
        code += {True: " with uncommitted changes", False: " (clean)"}.get(p["dirty"], "")
    return [f"{what}: bundledyn {p['bundledyn']}, {code}; run {p['date']} on {p['machine']}.", ""]
