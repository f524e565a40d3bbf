"""The plots of the seed 001 reproduction (see :mod:`.seed001`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from cosim.reproduce.seed001_runs import (
    AXES,
    HEADING_LIMIT,
    LEVER_ARMS,
    T_FROM,
    CampaignStats,
    RunHistory,
)


def rms_curve(runs: Sequence[RunHistory], k: int) -> np.ndarray:
    """RMS over the runs of axis ``k``'s error, per sample.

    Parameters
    ----------
    runs : sequence of RunHistory
        Runs on the same time grid.
    k : int
        0 roll, 1 pitch, 2 heading.

    Returns
    -------
    ndarray, shape (m,)
        [arcmin].
    """
    return np.sqrt(np.mean(np.array([r.err[:, k] ** 2 for r in runs]), axis=0))


def plot_modelled_ignored(
    path: Path,
    single: Mapping[tuple[float, str], RunHistory],
    camp: Mapping[tuple[float, str], list[RunHistory]],
    sigmas: Sequence[float],
) -> None:
    """Plot the single case and the campaigns' RMS, flexure modelled and ignored.

    Parameters
    ----------
    path : Path
        The PNG.
    single : dict
        (flexure sigma [arcmin], "modelled" or "ignored") -> the paper's single case.
    camp : dict
        The same keys -> the campaign's runs.
    sigmas : sequence of float
        Flexure sigmas [arcmin], one column each.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, len(sigmas), figsize=(6 * len(sigmas), 9), sharex=True)
    axes = np.atleast_2d(axes.T).T if len(sigmas) == 1 else axes
    colors = {"modelled": "tab:blue", "ignored": "tab:red"}
    limits = (6.0, 10.0, 25.0)
    for col, sig in enumerate(sigmas):
        for k in range(3):
            ax = axes[k, col]
            for lab in ("modelled", "ignored"):
                c = colors[lab]
                run = single[(sig, lab)]
                m = run.time >= 5.0
                t = run.time[m]
                ax.plot(t, run.err[m, k], color=c, lw=1.2, label=f"paper case, flexure {lab}")
                ax.fill_between(
                    t, -3 * run.sigma[m, k], 3 * run.sigma[m, k], color=c, alpha=0.10, lw=0
                )
                runs = camp[(sig, lab)]
                ax.plot(
                    t, rms_curve(runs, k)[m], color=c, ls="--", lw=1.0,
                    label=f"RMS over {len(runs)} runs, flexure {lab}",
                )  # fmt: skip
            ax.axhline(0.0, color="k", lw=0.5)
            if k == 2:
                ax.axhline(HEADING_LIMIT, color="k", ls=":", lw=0.8, label="7' requirement")
                ax.axhline(-HEADING_LIMIT, color="k", ls=":", lw=0.8)
            ax.set_ylim(-limits[k], limits[k])
            ax.set_ylabel(f"{AXES[k]} error [arcmin]")
            ax.grid(alpha=0.3)
        axes[0, col].set_title(f"flexure sigma {sig:g} arcmin (shaded: +-3 sigma of the filter)")
        axes[-1, col].set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    fig.suptitle("Seed 001: relative-attitude error, flexure modelled (19 states) and ignored (13)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_lever(
    path: Path,
    table: Mapping[tuple[float, float, str], CampaignStats],
    cov: Mapping[float, float],
    sigmas: Sequence[float],
) -> None:
    """Plot the heading and level RMS against the lever arm.

    Parameters
    ----------
    path : Path
        The PNG.
    table : dict
        (flexure sigma [arcmin], L [m], "modelled" or "ignored") -> statistics.
    cov : dict
        L [m] -> RMS heading sigma of the covariance analysis [arcmin].
    sigmas : sequence of float
        The two flexure sigmas drawn [arcmin].
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    styles = {sigmas[0]: "-", sigmas[1]: "--"}
    for sig in sigmas:
        for lab, c in (("modelled", "tab:blue"), ("ignored", "tab:red")):
            arms = [a for a in LEVER_ARMS if (sig, a, lab) in table]
            hd = [table[(sig, a, lab)].rms[2] for a in arms]
            lv = [math.sqrt(0.5 * np.sum(table[(sig, a, lab)].rms[:2] ** 2)) for a in arms]
            kw = {"color": c, "ls": styles[sig], "marker": "o"}
            axes[0].plot(arms, hd, label=f"flexure {sig:g}', {lab}", **kw)
            axes[1].plot(arms, lv, label=f"flexure {sig:g}', {lab}", **kw)
    arms = sorted(cov)
    axes[0].plot(
        arms, [cov[a] for a in arms], "k:", marker="x", label="covariance analysis (RMS sigma)"
    )
    axes[0].axhline(HEADING_LIMIT, color="k", lw=0.6)
    axes[0].set_yscale("log")
    axes[0].set_ylabel("heading error RMS from 30 s [arcmin]")
    axes[1].set_ylabel("level error RMS from 30 s [arcmin]")
    axes[1].set_yscale("log")
    for ax in axes:
        ax.set_xlabel("lever arm L [m], r0 = [L, L, L/2]")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_headings(path: Path, runs: Mapping[float, list[RunHistory]]) -> None:
    """Plot the heading RMS over time for each initial heading.

    Parameters
    ----------
    path : Path
        The PNG.
    runs : dict
        True mounting heading [deg] -> its runs.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.5))
    cmap = plt.get_cmap("viridis")
    for j, (hdg, rs) in enumerate(sorted(runs.items())):
        e = rms_curve(rs, 2)
        color = cmap(j / max(1, len(runs) - 1))
        ax.semilogy(rs[0].time, np.maximum(e, 1e-3), color=color, label=f"{hdg:g} deg")
    ax.axhline(HEADING_LIMIT, color="k", ls=":", lw=0.8, label="7'")
    ax.axvline(T_FROM, color="k", lw=0.5)
    ax.set_ylim(0.1, 1.5e4)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("heading error, RMS over runs [arcmin]")
    ax.set_title("Initial heading misalignment sweep (flexure modelled)")
    ax.legend(fontsize=7, ncol=4)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
