"""The built-in blocks' identities, worked out once in the local workers' forkserver.

Imported by the forkserver of local workers (:data:`cosim.verify.pool.PRELOAD`) only.

Importing this module works out the identity (GUID and source hash,
:func:`cosim.blocks.class_identity`, cached per process) of every built-in block class
(``models`` and ``cosim.alignment``) once, in the forkserver: every worker forked from it
then builds its blocks without reading their sources again (about 0.3 s of CPU per
worker for the transfer-alignment scenario, 0.5 s once in the forkserver for all
built-in blocks). A block that cannot be loaded is left to the worker, which reports it.
It also looks up the software versions written into every result
(:func:`cosim.provenance.versions`, cached per process: about 3 ms of metadata look-ups
that each worker would pay while building its blocks).
"""

from __future__ import annotations

import contextlib

from cosim import provenance, registry
from cosim.blocks import class_identity

__all__ = ["IDENTIFIED"]


def _identify_builtin_blocks() -> tuple[str, ...]:
    done = []
    for name in registry.names():
        with contextlib.suppress(Exception):
            cls = registry.find_block(name)
            if cls.__module__.startswith(("cosim.models.", "cosim.alignment.")):
                class_identity(cls)
                done.append(name)
    return tuple(done)


#: The built-in blocks whose identity this process has cached.
IDENTIFIED = _identify_builtin_blocks()
provenance.versions()
