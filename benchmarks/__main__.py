"""Run every benchmark module and print one table; write benchmarks/results.json.

Each ``benchmarks/bench_<name>.py`` defines ``bench() -> list[dict]``; a row has
``name``, ``ratio`` (the figure that is judged, measured side by side in this run),
``target`` (a string such as ``"<= 2"``), ``met`` (bool or None) and ``info`` (absolute
times, for information only: these machines are noisy).
"""

from __future__ import annotations

import importlib
import json
import pkgutil
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(selected: list[str]) -> int:
    rows: list[dict] = []
    for info in sorted(pkgutil.iter_modules([str(HERE)]), key=lambda m: m.name):
        if not info.name.startswith("bench_"):
            continue
        if selected and info.name.removeprefix("bench_") not in selected:
            continue
        start = time.perf_counter()
        print(f"running {info.name} ...", file=sys.stderr, flush=True)
        try:  # a broken row is reported as such; the other rows still run
            module = importlib.import_module(f"benchmarks.{info.name}")
            got = module.bench()
        except Exception as exc:
            got = [{"name": info.name, "met": None, "info": f"failed: {type(exc).__name__}: {exc}"}]
        for row in got:
            row.setdefault("module", info.name)
            rows.append(row)
        print(f"  {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
    width = max((len(r["name"]) for r in rows), default=10)
    print(f"{'benchmark':<{width}}  {'ratio':>9}  {'target':<8}  {'met':<4}  info")
    for r in rows:
        met = {True: "yes", False: "NO", None: "-"}[r.get("met")]
        ratio = r.get("ratio")
        ratio_text = f"{ratio:9.3g}" if isinstance(ratio, (int, float)) else f"{'-':>9}"
        print(
            f"{r['name']:<{width}}  {ratio_text}  {r.get('target', ''):<8}  {met:<4}  "
            f"{r.get('info', '')}"
        )
    (HERE / "results.json").write_text(json.dumps(rows, indent=2, default=str) + "\n")
    print(f"wrote {HERE / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
