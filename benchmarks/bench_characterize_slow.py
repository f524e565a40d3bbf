"""Characterise a 24-hour, 200 Hz, 6-channel log (issue 28, acceptance 1): slow.

``make bench-slow`` (or ``python -m benchmarks.bench_characterize_slow [HOURS]``) writes
a static IMU log of ``HOURS`` (24) hours at 200 Hz as HDF5 (17.3 million samples a
channel, 1 GB), each channel the sum of white rate noise, flicker (bias instability) and
rate random walk of known levels (:data:`LEVELS`, drawn by
:func:`cosim.sensors.characterize.simulate`), then, in the same run:

* ``ins-cosim characterize LOG --out DIR`` in a child process: its wall time (the
  interpreter's start and imports included) and its peak resident memory (``VmHWM`` of
  its own address space, which it reads from ``/proc/self/status`` as it ends: a child's
  ``ru_maxrss`` would count the parent's pages at the fork);
* allantools ``oadev`` alone on the same six channels at the same octave averaging
  times, in another child process (the channels read before the timing, which covers the
  ``oadev`` calls only), before and after the command; the faster of the two is kept.

Judged: peak RSS <= 1.5 GiB; characterize's wall time <= 3 x ``oadev``'s; the fitted
white, bias-instability and random-walk terms of every channel within their 95 %
intervals, counted: at least ``18 x 0.95 - 3 binomial sigmas`` (15) of the 18 (all 18
is what one expects most often, 40 % of seeds would have a miss). Not in
``make bench``'s table: :func:`bench` gives no row unless ``INS_COSIM_BENCH_SLOW=1``.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.timing import ROOT, load_note

HOURS = 24.0
RATE = 200.0
SEED = 28
#: Limits of acceptance 1.
RSS_LIMIT = 1.5 * 2**30
TIME_LIMIT = 3.0
ENV = "INS_COSIM_BENCH_SLOW"
CHANNELS = ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
#: Per channel (N white [unit sqrt(s)], B bias instability [unit], K random walk
#: [unit / sqrt(s)]), SI: a tactical gyro (0.005 deg/sqrt(h), 0.05 deg/h, K crossing B at
#: ~3000 s) and accelerometer (30 ug/sqrt(Hz), 10 ug, K crossing B at ~3000 s).
LEVELS = {
    "gyro": (1.454e-6, 2.424e-7, 5.0e-9),
    "acc": (2.94e-4, 9.81e-5, 2.0e-6),
}
#: Gravity and Earth rate in the log (a constant does not enter the Allan variance).
MEAN = {"gyro": 7.292e-5, "acc": -9.81}


def write_log(path: Path, hours: float = HOURS, rate: float = RATE, seed: int = SEED) -> int:
    """Write the static HDF5 log of the benchmark, one channel at a time.

    Parameters
    ----------
    path : Path
        The ``.h5`` file (overwritten).
    hours : float
        Length [h].
    rate : float
        Sample rate [Hz].
    seed : int
        Seed of the noise (channel ``i`` uses ``SeedSequence(seed).spawn(6)[i]``).

    Returns
    -------
    int
        Samples per channel.
    """
    import h5py

    from cosim.sensors.characterize import simulate

    n = int(round(hours * 3600.0 * rate))
    dt = 1.0 / rate
    seeds = np.random.SeedSequence(seed).spawn(len(CHANNELS))
    with h5py.File(path, "w") as f:
        t = f.create_dataset("time", data=np.arange(1, n + 1) * dt)
        t.attrs["unit"] = "s"
        for name, ss in zip(CHANNELS, seeds, strict=True):
            kind = name.split("_")[0]
            white, b, k = LEVELS[kind]
            c = np.array([0.0, white**2, b**2, k**2])
            y = simulate(c, n, dt, np.random.default_rng(ss)) + MEAN[kind]
            ds = f.create_dataset(name, data=y)
            ds.attrs["unit"] = "rad/s" if kind == "gyro" else "m/s2"
            del y
    return n


_OADEV = """
import json, sys, time
import allantools, h5py, numpy as np
from cosim.sensors.characterize import octave_factors
path, rate = sys.argv[1], float(sys.argv[2])
total = 0.0
with h5py.File(path, "r") as f:
    for name in ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"):
        y = np.asarray(f[name][:], dtype=float)
        m = octave_factors(len(y))
        start = time.perf_counter()
        allantools.oadev(y, rate=rate, data_type="freq", taus=m / rate)
        total += time.perf_counter() - start
        del y
print(json.dumps({"oadev": total}))
"""

_CHARACTERIZE = """
import json, sys
from cosim.cli import main
try:
    main(["characterize", *sys.argv[1:]], standalone_mode=False)
finally:
    status = open("/proc/self/status").read()
    hwm = int(status.split("VmHWM:")[1].split()[0]) * 1024
    print(json.dumps({"vmhwm": hwm}))
"""

_WRITE = """
import sys
from pathlib import Path
from benchmarks.bench_characterize_slow import write_log
print(write_log(Path(sys.argv[1]), float(sys.argv[2])))
"""


def _run(code: str, *args: str) -> tuple[float, str]:
    """Run ``python -c code args`` from the repository: its wall time [s] and stdout."""
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", code, *args], cwd=ROOT, capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    if proc.returncode:
        raise RuntimeError(f"child process failed: {proc.stderr.strip()[-400:]}")
    return wall, proc.stdout


def coverage(doc: dict[str, Any], dt: float) -> tuple[int, int, list[str]]:
    """Fitted terms of ``characterization.json`` within their intervals, against LEVELS.

    Parameters
    ----------
    doc : dict
        The json.
    dt : float
        Sample interval [s] (unused by the SI levels; kept for the message).

    Returns
    -------
    hits, total : int
        Terms (white, bias instability, random walk per channel) whose interval holds
        the generated level, of those fitted.
    misses : list of str
        The others, ``"gyro_x random_walk 1.2e-9 not in [..]"``.
    """
    del dt
    hits = total = 0
    misses = []
    for name, entry in doc["axes"].items():
        kind = name.split("_")[0]
        terms = ("white", "bias_instability", "random_walk")
        for term, truth in zip(terms, LEVELS[kind], strict=True):
            got = entry["terms"][term]
            low, high = got["low_si"], got["high_si"]
            total += 1
            if low <= truth <= high:
                hits += 1
            else:
                misses.append(f"{name} {term} {truth:.4g} not in [{low:.4g}, {high:.4g}]")
    return hits, total, misses


def measure(hours: float = HOURS) -> dict[str, Any]:
    """Generate the log, characterise it, time oadev; the benchmark row.

    Parameters
    ----------
    hours : float
        Length of the log [h] (24 for the judged figure).

    Returns
    -------
    dict
        The row: ``ratio`` = characterize's wall time / oadev's, ``met`` for all three
        limits (None when ``hours`` is not 24).
    """
    name = f"characterize a {hours:g} h 200 Hz 6-channel log: wall time / allantools oadev"
    before = load_note()
    with tempfile.TemporaryDirectory(prefix="ins_cosim_bench_char_") as tmp:
        log = Path(tmp) / "static_24h.h5"
        written, out = _run(_WRITE, str(log), str(hours))  # its memory is not ours
        n = int(out.split()[-1])
        t1 = json.loads(_run(_OADEV, str(log), str(RATE))[1])["oadev"]
        wall, out = _run(_CHARACTERIZE, str(log), "--out", str(Path(tmp) / "char"))
        rss = json.loads(out.strip().splitlines()[-1])["vmhwm"]
        t2 = json.loads(_run(_OADEV, str(log), str(RATE))[1])["oadev"]
        doc = json.loads((Path(tmp) / "char" / "characterization.json").read_text())
    oadev = min(t1, t2)
    ratio = wall / oadev
    hits, total, misses = coverage(doc, 1.0 / RATE)
    need = math.ceil(total * 0.95 - 3.0 * math.sqrt(total * 0.95 * 0.05))
    judged = hours == HOURS
    ok = ratio <= TIME_LIMIT and rss <= RSS_LIMIT and hits >= need
    return {
        "name": name,
        "ratio": ratio,
        "target": f"<= {TIME_LIMIT:g}",
        "met": ok if judged else None,
        "rss": rss,
        "hits": hits,
        "info": (
            f"{n} samples a channel; characterize {wall:.1f} s (whole command), oadev alone "
            f"{t1:.1f} s before and {t2:.1f} s after (best kept); peak RSS "
            f"{rss / 2**20:.0f} MiB (limit {RSS_LIMIT / 2**20:.0f}); terms within their 95 % "
            f"intervals {hits} of {total} (needed {need})"
            + (f": missed {'; '.join(misses)}" if misses else "")
            + f"; log written in {written:.0f} s; {before} before, {load_note()} after"
        ),
    }


def bench() -> list[dict[str, Any]]:
    """The row, only when ``INS_COSIM_BENCH_SLOW=1`` (``make bench-slow``)."""
    if os.environ.get(ENV) != "1":
        return []
    return [measure(HOURS)]


if __name__ == "__main__":
    result = measure(float(sys.argv[1]) if len(sys.argv) > 1 else HOURS)
    met = {True: "yes", False: "NO", None: "-"}[result["met"]]
    print(f"{result['name']}: {result['ratio']:.2f} (target {result['target']}, met {met})")
    print(f"  {result['info']}")
