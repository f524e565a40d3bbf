"""Software provenance written into every result and report."""

from __future__ import annotations

import functools
import platform
from importlib import metadata

_PACKAGES = ("ins-cosim", "numpy", "scipy", "control", "fmpy", "pythonfmu", "pint")


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a result depends on.

    Looked up once per process (a look-up scans every ``sys.path`` entry, and the
    metadata library keeps a cache entry per folder it scanned).

    Returns
    -------
    dict
        ``{"python": "3.11.7", "numpy": "2.1.0", ...}``; missing packages are omitted.
    """
    return dict(_versions())


@functools.cache
def _versions() -> dict[str, str]:
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out
