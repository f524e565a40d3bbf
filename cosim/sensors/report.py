"""``ins-cosim characterize LOG --out DIR``: a static log's noise terms, plot and IMU parameters.

Writes into ``DIR``:

=======================  ===================================================================
file                     content
=======================  ===================================================================
``allan.csv``            per axis: tau [s], adev and its 68 % band, edf, fitted adev, in the
                         display units (gyro deg/h, accelerometer ug)
``characterization.json``  the fitted terms per axis with their confidence intervals (SI and
                         display units), the closest grade, the log's provenance
``allan.png``            log-log Allan deviation per triad with the bands and fitted lines
``imu_parameters.toml``  a ``[blocks.imu]`` table for a scenario (StrapdownImu parameter
                         names, scenario units)
=======================  ===================================================================

The log must be static (the sensor at rest, no rotation other than the Earth's): the
mean (gravity, Earth rate, fixed bias) does not enter the Allan deviation, but motion
would. The log is read once, chunk by chunk (:class:`cosim.estimation.allan.OctaveAllan`):
the memory is the read buffer's, whatever the log's length. Any non-empty subset of the
six sensor columns is analysed (a gyro-only log, one axis), each named by its header; the
outputs name only the axes and triads fitted. The StrapdownImu takes one value per
triad: the parameter block gives the root mean square over the triad's fitted axes of
each term, an axis where the term is not resolved (its confidence interval reaches zero)
counting zero (per-axis values and upper bounds in the json).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.estimation.allan import OctaveAllan
from cosim.sensors.characterize import (
    TERMS,
    AxisFit,
    Grade,
    allantools_module,
    closest_grade,
    fit_axis,
)
from cosim.sensors.formats import LogValueError
from cosim.sensors.logs import CHUNK_ROWS, JITTER, ImuLog
from cosim.units import conversion_factor

AXES = ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
#: Display units of each term, per triad: (Q, N, B, K), and the adev plot unit.
DISPLAY = {
    "gyro": {"terms": ("arcsec", "deg/sqrt(h)", "deg/h", "deg/h/sqrt(h)"), "adev": "deg/h"},
    "acc": {"terms": ("mm/s", "ug/sqrt(Hz)", "ug", "ug/sqrt(s)"), "adev": "ug"},
}
_SI = {
    "gyro": ("rad", "rad/sqrt(s)", "rad/s", "rad/s/sqrt(s)"),
    "acc": ("m/s", "m/s/sqrt(s)", "m/s2", "m/s2/sqrt(s)"),
}
#: StrapdownImu parameter of each term (lsb is sqrt(12) Q; bi_sigma / bi_tau from B).
PARAMETER = {
    "gyro": ("gyro_lsb", "gyro_arw", "gyro_bi_sigma", "gyro_rrw"),
    "acc": ("accel_lsb", "accel_vrw", "accel_bi_sigma", "accel_rrw"),
}


@dataclass
class Characterization:
    """The result of :func:`characterize_log`.

    Attributes
    ----------
    log : Path
        The log.
    sha256 : str
        Its hash.
    samples : int
        Samples analysed.
    dt : float
        Sample interval [s].
    axes : dict of str to AxisFit
        Per axis fitted (those of :data:`AXES` the log holds, in that order), SI units.
    grade : Grade
        The closest preset (:data:`GRADE0`, nameless, when no figure could be compared).
    distance : float
        Its distance [decades].
    """

    log: Path
    sha256: str
    samples: int
    dt: float
    axes: dict[str, AxisFit]
    grade: Grade
    distance: float

    @property
    def triads(self) -> tuple[str, ...]:
        """The triads with at least one axis fitted: ``"gyro"``, ``"acc"``, in that order."""
        return tuple(p for p in ("gyro", "acc") if self.triad(p))

    def triad(self, prefix: str) -> list[AxisFit]:
        """The fitted axes of ``"gyro"`` or ``"acc"`` (x, y, z order; empty if none).

        Parameters
        ----------
        prefix : str
            ``"gyro"`` or ``"acc"``.

        Returns
        -------
        list of AxisFit
        """
        return [self.axes[f"{prefix}_{a}"] for a in "xyz" if f"{prefix}_{a}" in self.axes]

    def rms(self, prefix: str, j: int) -> float:
        """Root mean square over the triad's fitted axes of term ``j`` where resolved (SI).

        An axis on which the term is not resolved (its interval reaches 0) counts 0.

        Parameters
        ----------
        prefix : str
            ``"gyro"`` or ``"acc"``.
        j : int
            Index in :data:`cosim.sensors.characterize.TERMS`.

        Returns
        -------
        float
        """
        fits = self.triad(prefix)
        return math.sqrt(sum(f.resolved[j] ** 2 for f in fits) / len(fits))

    def gauss_markov(self, prefix: str) -> tuple[float, float]:
        """Triad's Gauss-Markov bias: RMS sigma, mean correlation time (axes with flicker).

        Parameters
        ----------
        prefix : str
            ``"gyro"`` or ``"acc"``.

        Returns
        -------
        sigma : float
            [rad/s or m/s2].
        tau_c : float
            [s].
        """
        pairs = [f.gauss_markov() for f in self.triad(prefix)]
        sigma = math.sqrt(sum(s * s for s, _ in pairs) / len(pairs))
        taus = [t for s, t in pairs if s > 0.0]
        return sigma, (float(np.mean(taus)) if taus else 3600.0)


def characterize_log(
    path: str | Path,
    *,
    sample_rate: float | None = None,
    jitter: float = JITTER,
    duplicates: str = "error",
    boot: int = 1000,
    level: float = 0.95,
    seed: int = 0,
    chunk_rows: int = CHUNK_ROWS,
) -> Characterization:
    """Allan analysis of every sensor axis a static IMU log holds, in one streaming pass.

    Parameters
    ----------
    path : str or Path
        The log (:mod:`cosim.sensors.logs`; every check applies), with any non-empty
        subset of the six sensor columns.
    sample_rate : float, optional
        Nominal sample rate [Hz]; default from the timestamps.
    jitter : float, optional
        Timestamp tolerance [sample intervals].
    duplicates : {"error", "drop"}, optional
        Duplicate-row policy.
    boot : int, optional
        Bootstrap refits of the Allan variances per axis for the confidence intervals.
    level : float, optional
        Confidence level.
    seed : int, optional
        Bootstrap seed (axis ``AXES[i]`` uses ``seed + i``).
    chunk_rows : int, optional
        Rows read at a time: with the analysis's own ~1 MB, the memory bound.

    Returns
    -------
    Characterization

    Raises
    ------
    LogError
        The log fails a check, has no sensor column, or has fewer than 16 samples.
    UserError
        allantools (the ``allan`` extra) is not installed: said before the log is read.
    """
    allantools_module()
    log = ImuLog(
        path,
        sample_rate=sample_rate,
        jitter=jitter,
        duplicates=duplicates,
        chunk_rows=chunk_rows,
        partial=True,
    )
    names = log.columns.present
    allan = OctaveAllan(len(names))
    for chunk in log.chunks():
        allan.update(chunk.values)
    n = allan.count
    if n < 16:
        raise LogValueError(
            str(path),
            f"{n} samples, too few for an Allan analysis",
            "record at least 16 samples (hours for the bias instability and random walk)",
        )
    dt = 1.0 / log.sample_rate
    m, avar = allan.avar(dt)
    axes = {
        name: fit_axis(m, avar[:, i], n, dt, boot=boot, level=level, seed=seed + AXES.index(name))
        for i, name in enumerate(names)
    }
    result = Characterization(Path(path), stream_sha256(Path(path)), n, dt, axes, GRADE0, 0.0)
    gyro, acc = ("gyro" in result.triads), ("acc" in result.triads)
    figures = {
        "gyro_bi": result.rms("gyro", 2) if gyro else None,
        "gyro_arw": result.rms("gyro", 1) if gyro else None,
        "accel_bi": result.rms("acc", 2) if acc else None,
        "accel_vrw": result.rms("acc", 1) if acc else None,
    }
    try:
        result.grade, result.distance = closest_grade(**figures)
    except ValueError:  # no figure > 0: nothing to compare
        pass
    return result


GRADE0 = Grade("", 0.0, 0.0, 0.0, 0.0, "")


def stream_sha256(path: Path) -> str:
    """SHA-256 of a file read in blocks (a 24-hour log is not held in memory).

    Parameters
    ----------
    path : Path
        The file.

    Returns
    -------
    str
        64 lower-case hex digits, as :func:`cosim.blocks.file_sha256` gives them.
    """
    with path.open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def parameter_block(result: Characterization) -> str:
    """A ``[blocks.imu]`` table for a scenario: StrapdownImu names, scenario units.

    Parameters
    ----------
    result : Characterization
        From :func:`characterize_log`.

    Returns
    -------
    str
        TOML text (comments first), ready to paste.
    """
    values: dict[str, str] = {"grade": "0"}
    for prefix in result.triads:
        names = PARAMETER[prefix]
        units = DISPLAY[prefix]["terms"]
        si = _SI[prefix]
        q = result.rms(prefix, 0) * math.sqrt(12.0)
        values[names[0]] = f'"{_fmt(q * conversion_factor(si[0], units[0]))} {units[0]}"'
        n = result.rms(prefix, 1) * conversion_factor(si[1], units[1])
        values[names[1]] = f'"{_fmt(n)} {units[1]}"'
        sigma, tau_c = result.gauss_markov(prefix)
        values[names[2]] = f'"{_fmt(sigma * conversion_factor(si[2], units[2]))} {units[2]}"'
        values[names[2].replace("sigma", "tau")] = f'"{_fmt(tau_c)} s"'
        k = result.rms(prefix, 3) * conversion_factor(si[3], units[3])
        values[names[3]] = f'"{_fmt(k)} {units[3]}"'
    body = ", ".join(f"{k} = {v}" for k, v in values.items())
    fitted = ", ".join(result.axes)
    missing = [p for p in ("gyro", "acc") if p not in result.triads]
    grade = (
        f"{result.grade.name} ({result.distance:.2f} decades)"
        if result.grade.name
        else "none (no figure > 0 to compare)"
    )
    lines = [
        f"# ins-cosim characterize {result.log.name} (sha256 {result.sha256[:12]}): "
        f"{result.samples} samples at {1.0 / result.dt:.6g} Hz "
        f"({result.samples * result.dt:.6g} s)",
        f"# axes fitted: {fitted}"
        + (
            f" (no {' or '.join(missing)} column: the model keeps its defaults there)"
            if missing
            else ""
        ),
        "# RMS over the fitted axes of each triad (0 where a term is not resolved: its upper "
        "bound is in characterization.json);",
        "# bias instability as a first-order Gauss-Markov bias",
        "# (matches the flicker floor only around its minimum); turn-on bias, scale factor and",
        "# misalignment are not observable in one static log: set them from the data sheet.",
        f"# closest grade preset: {grade}",
        "[blocks.imu]",
        'model = "StrapdownImu"',
        f"parameters = {{ {body} }}",
    ]
    return "\n".join(lines) + "\n"


def _triad_json(result: Characterization, prefix: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    units = DISPLAY[prefix]["terms"]
    for axis in "xyz":
        fit = result.axes.get(f"{prefix}_{axis}")
        if fit is None:
            continue
        terms = {}
        for j, term in enumerate(TERMS):
            f = conversion_factor(_SI[prefix][j], units[j])
            terms[term] = {
                "value": fit.value[j] * f,
                "low": fit.low[j] * f,
                "high": fit.high[j] * f,
                "unit": units[j],
                "value_si": fit.value[j],
                "low_si": fit.low[j],
                "high_si": fit.high[j],
                "unit_si": _SI[prefix][j],
            }
        sigma, tau_c = fit.gauss_markov()
        out[f"{prefix}_{axis}"] = {
            "terms": terms,
            "level": fit.level,
            "gauss_markov": {"sigma_si": sigma, "tau_c_s": tau_c},
        }
    return out


def write_outputs(result: Characterization, out_dir: str | Path) -> dict[str, Path]:
    """Write ``allan.csv``, ``characterization.json``, ``allan.png``, ``imu_parameters.toml``.

    Parameters
    ----------
    result : Characterization
        From :func:`characterize_log`.
    out_dir : str or Path
        Destination folder (created).

    Returns
    -------
    dict of str to Path
        ``{"csv", "json", "png", "toml"}`` -> file.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = ["axis,tau [s],adev,band_low,band_high,edf,fit,unit"]
    for name, fit in result.axes.items():
        unit = DISPLAY[name.split("_")[0]]["adev"]
        f = conversion_factor("rad/s" if name.startswith("gyro") else "m/s2", unit)
        model = fit.model(fit.tau)
        for k, tau in enumerate(fit.tau):
            rows.append(
                f"{name},{tau!r},{fit.adev[k] * f!r},{fit.band[k, 0] * f!r},"
                f"{fit.band[k, 1] * f!r},{fit.edf[k]:.6g},{model[k] * f!r},{unit}"
            )
    paths = {
        "csv": out / "allan.csv",
        "json": out / "characterization.json",
        "png": out / "allan.png",
        "toml": out / "imu_parameters.toml",
    }
    paths["csv"].write_text("\n".join(rows) + "\n")
    doc = {
        "log": str(result.log),
        "sha256": result.sha256,
        "samples": result.samples,
        "sample_rate_hz": 1.0 / result.dt,
        "axes_fitted": list(result.axes),
        "axes": {**_triad_json(result, "gyro"), **_triad_json(result, "acc")},
        "closest_grade": {
            "name": result.grade.name,
            "distance_decades": result.distance,
            "source": result.grade.source,
        },
        "method": "overlapping Allan deviation at octave averaging times, streamed "
        "(cosim.estimation.allan.OctaveAllan), IEEE Std 952 / 1293 terms fitted by "
        "non-negative weighted least squares, intervals from a parametric bootstrap of the "
        "Allan variances with Greenhall's chi-square equivalent degrees of freedom",
    }
    paths["json"].write_text(json.dumps(doc, indent=2) + "\n")
    paths["toml"].write_text(parameter_block(result))
    plot(result, paths["png"])
    return paths


def plot(result: Characterization, path: Path) -> Path:
    """Log-log Allan deviation per triad, with 68 % bands and the fitted lines.

    Parameters
    ----------
    result : Characterization
        From :func:`characterize_log`.
    path : Path
        The PNG file.

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cosim.sensors.characterize import design

    triads = result.triads
    fig, axes = plt.subplots(1, len(triads), figsize=(6 * len(triads), 5), squeeze=False)
    labels = ("quantisation", "white (ARW/VRW)", "bias instability", "random walk")
    for ax, prefix in zip(axes[0], triads, strict=True):
        unit = DISPLAY[prefix]["adev"]
        f = conversion_factor("rad/s" if prefix == "gyro" else "m/s2", unit)
        first = result.triad(prefix)[0]
        for axis, color in zip("xyz", ("C0", "C1", "C2"), strict=True):
            fit = result.axes.get(f"{prefix}_{axis}")
            if fit is None:
                continue
            ax.fill_between(fit.tau, fit.band[:, 0] * f, fit.band[:, 1] * f, color=color, alpha=0.2)
            ax.loglog(fit.tau, fit.adev * f, "o", ms=3, color=color, label=f"{prefix}_{axis}")
            grid = np.geomspace(fit.tau[0], fit.tau[-1], 200)
            ax.loglog(grid, fit.model(grid) * f, "-", color=color, lw=1)
            parts = design(grid) * fit.value**2
            for j, style in enumerate((":", "--", "-.", (0, (1, 3)))):
                if fit.value[j] > 0.0 and fit is first:
                    ax.loglog(grid, np.sqrt(parts[:, j]) * f, ls=style, color="0.4", lw=0.8,
                              label=f"{labels[j]} ({axis})")  # fmt: skip
        low = min(float(np.min(fit.band[:, 0])) for fit in result.triad(prefix))
        ax.set_ylim(bottom=0.3 * low * f)  # the fitted terms, where they matter
        ax.set_xlabel("averaging time tau [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(f"{prefix}: overlapping ADEV, 68 % band, fitted terms")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{result.log.name}: closest grade {result.grade.name or 'none'}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
