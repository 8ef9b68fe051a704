"""A stress case's outcome (`StressRow`) and the battery's (`StressReport`)."""

import math

import equinox as eqx


class StressRow(eqx.Module):
    """What one stress case showed: the measured figure against its bound.

    **Fields:**

    - `case`: the case's name (its function in `bundledyn.stress`).
    - `shows`: what the figure measures, in a line.
    - `measured`: the figure (NaN when the run did not produce one: it fails).
    - `bound`: the largest figure that passes.
    - `note`: the reason of a failure, or what the reader should know of a pass.
    """

    case: str
    shows: str
    measured: float
    bound: float
    note: str = ""

    @property
    def passed(self) -> bool:
        """Whether the figure is finite and within its bound."""
        return math.isfinite(self.measured) and self.measured <= self.bound


def table_cell(text: str) -> str:
    """`text` safe in a Markdown table cell (its bars escaped: `|ω|` is not a column)."""
    return text.replace("|", "\\|")


def _verdict(row: StressRow) -> str:
    return "pass" if row.passed else "FAIL"


class StressReport(eqx.Module):
    """The rows of a battery run on one model, printable as a table.

    **Fields:**

    - `model`: what the battery ran on (the shipped cases, or the user's model file).
    - `rows`: one `StressRow` per measured figure.
    """

    model: str
    rows: tuple[StressRow, ...]

    @property
    def passed(self) -> bool:
        """Whether every row passed."""
        return all(row.passed for row in self.rows)

    @property
    def failed(self) -> tuple[StressRow, ...]:
        """The rows that did not pass."""
        return tuple(row for row in self.rows if not row.passed)

    def __str__(self) -> str:
        width = max([len(row.case) for row in self.rows] + [4])
        lines = [
            f"Stress battery on {self.model}: "
            + ("PASSED" if self.passed else f"FAILED {len(self.failed)} of {len(self.rows)}"),
            f"  {'case':{width}}  {'measured':>9}  {'bound':>9}        shows",
        ]
        for row in self.rows:
            lines.append(
                f"  {row.case:{width}}  {row.measured:9.1e}  {row.bound:9.1e}  {_verdict(row)}  "
                f"{row.shows}" + (f" — {row.note}" if row.note else "")
            )
        return "\n".join(lines)

    def markdown(self) -> str:
        """The report as a Markdown table (the README's)."""
        lines = ["| case | shows | measured | bound | |", "|---|---|---:|---:|---|"]
        for row in self.rows:
            note = f" ({row.note})" if row.note else ""
            lines.append(
                f"| `{row.case}` | {table_cell(row.shows + note)} | {row.measured:.1e} "
                f"| {row.bound:.0e} | {_verdict(row)} |"
            )
        return "\n".join(lines)
