"""What the benchmarks' diagrams share."""


def pyplot():
    """matplotlib's `pyplot` on its file backend (Agg); None, saying so, without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("  matplotlib is not installed: no diagram (pip install '.[viz]')")
        return None
    return plt
