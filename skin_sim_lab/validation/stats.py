"""Table II of the paper, redone with scipy: a two-sample equal-variance t-test.

Rows as in the paper (Excel's "t-Test: Two-Sample Assuming Equal Variances"): mean,
variance (sample, ddof = 1), observations, pooled variance, hypothesised mean difference,
df, t Stat, one- and two-tail p and t critical values at alpha = 0.05.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

ROWS = (
    "Mean", "Variance", "Observations", "Pooled Variance", "Hypothesized Mean Difference", "df", "t Stat",
    "P(T<=t) one-tail", "t Critical one-tail", "P(T<=t) two-tail", "t Critical two-tail",
)  # fmt: skip


def table_ii(a, b, alpha: float = 0.05) -> dict:
    """The Table II statistics of samples ``a`` (FEA column) and ``b`` (model column)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    na, nb = a.size, b.size
    df = na + nb - 2
    pooled = ((na - 1) * a.var(ddof=1) + (nb - 1) * b.var(ddof=1)) / df
    test = stats.ttest_ind(a, b, equal_var=True)
    t = float(test.statistic)
    return {
        "Mean": (float(a.mean()), float(b.mean())),
        "Variance": (float(a.var(ddof=1)), float(b.var(ddof=1))),
        "Observations": (na, nb),
        "Pooled Variance": float(pooled),
        "Hypothesized Mean Difference": 0.0,
        "df": df,
        "t Stat": t,
        "P(T<=t) one-tail": float(stats.t.sf(abs(t), df)),
        "t Critical one-tail": float(stats.t.ppf(1 - alpha, df)),
        "P(T<=t) two-tail": float(test.pvalue),
        "t Critical two-tail": float(stats.t.ppf(1 - alpha / 2, df)),
    }


def table_markdown(table: dict, names=("FEA", "Wave Equation")) -> str:
    """Table II as a markdown table."""
    lines = [f"| | {names[0]} | {names[1]} |", "|---|---|---|"]
    for row in ROWS:
        v = table[row]
        if isinstance(v, tuple):
            lines.append(f"| {row} | {v[0]:.6g} | {v[1]:.6g} |")
        else:
            lines.append(f"| {row} | {v:.6g} | |")
    return "\n".join(lines)
