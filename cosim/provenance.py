"""Software provenance written into every result and report."""

from __future__ import annotations

import functools
import platform
from importlib import metadata

from cosim.models import native

_PACKAGES = ("ins-cosim", "numpy", "scipy", "control", "fmpy", "pythonfmu", "pint")


def versions(extra: tuple[str, ...] = ()) -> dict[str, str]:
    """Versions of Python and of the packages a result depends on.

    Looked up once per process for each ``extra`` (a look-up scans every ``sys.path``
    entry, and the metadata library keeps a cache entry per folder it scanned).

    Parameters
    ----------
    extra : tuple of str
        More distributions to look up after the fixed ones (a campaign's report adds the
        packages it uses).

    Returns
    -------
    dict
        ``{"python": "3.11.7", "platform": ..., "kernels": "compiled kernels
        (kernels-<hash>.so)", "numpy": "2.1.0", ...}``; missing packages are omitted.
        ``kernels`` is the path the
        models' steps take in this process and why (:func:`cosim.models.native.status`:
        compiled, or numpy with the reason).
    """
    found = _versions(tuple(extra))
    head = {"python": found["python"], "platform": found["platform"], "kernels": native.status()}
    return {**head, **found}


@functools.cache
def _versions(extra: tuple[str, ...]) -> dict[str, str]:
    out = {"python": platform.python_version(), "platform": platform.platform()}
    for name in (*_PACKAGES, *extra):
        try:
            out[name] = name_and_version(metadata.distribution(name))[1]
        except metadata.PackageNotFoundError:
            continue
    return out


def name_and_version(dist: metadata.Distribution) -> tuple[str, str]:
    """A distribution's ``Name`` and ``Version``, read from the header of its metadata file.

    ``dist.metadata`` (and ``metadata.version``) parse the whole file as an e-mail message,
    long description included (ins-cosim's is its README: about 2 ms per parse; the block
    registry reads two fields per entry point, :func:`versions` one per package, in every
    worker process); the two fields are in the header, before the first blank line.

    Parameters
    ----------
    dist : importlib.metadata.Distribution
        An installed distribution.

    Returns
    -------
    tuple of str
        ``(name, version)``, as ``dist.metadata["Name"]`` and ``dist.version`` give them
        (which answer when the header lacks either field).
    """
    text = dist.read_text("METADATA") or dist.read_text("PKG-INFO") or ""
    fields: dict[str, str] = {}
    for line in text.split("\n\n", 1)[0].splitlines():
        key, sep, value = line.partition(":")
        if sep and key in ("Name", "Version") and key not in fields:
            fields[key] = value.strip()
    if len(fields) < 2:  # no metadata file or an unusual one: the full parse
        return dist.metadata["Name"], dist.version
    return fields["Name"], fields["Version"]
