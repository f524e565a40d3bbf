"""Plots of run results (matplotlib, no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from cosim.results import RunResult  # noqa: E402

# Display units for SI units: (label, factor from SI).
DISPLAY = {
    "rad": ("arcmin", 1.0 / 2.908882086657216e-4),
    "rad/s": ("deg/h", 1.0 / 4.84813681109536e-06),
    "m/s2": ("mg", 1.0 / 9.80665e-3),
}


def plot_result(result: RunResult, path: Path, title: str = "") -> Path:
    """One panel per block and unit, every recorded signal against time.

    Parameters
    ----------
    result : RunResult
        The run; angles are drawn in arcmin, rates in deg/h, specific force in mg.
    path : Path
        PNG file to write.
    title : str
        Figure title.

    Returns
    -------
    Path
        The PNG written.
    """
    units = result.metadata.get("units", {})
    groups: dict[str, list[str]] = {}
    for name in result.names[1:]:
        label = DISPLAY.get(units.get(name, ""), (units.get(name, ""), 1.0))[0]
        groups.setdefault(f"{name.split('.', 1)[0]} [{label}]", []).append(name)
    n = max(1, len(groups))
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.6 * n), sharex=True, squeeze=False)
    t = result.time
    for ax, (block, cols) in zip(axes[:, 0], groups.items(), strict=False):
        for c in cols:
            factor = DISPLAY.get(units.get(c, ""), ("", 1.0))[1]
            ax.plot(t, result.data[c] * factor, lw=0.8, label=c)
        ax.set_ylabel(block)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
