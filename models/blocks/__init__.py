"""The model blocks: one module per block class, each a truth or sensor model.

Every module here defines block classes (:class:`cosim.models.block.Block` subclasses)
and nothing else a scenario could not name; what several blocks share lives in the
model library one folder up (:mod:`cosim.models`). :func:`cosim.models.truth_models`
finds the classes; a module's C kernel (``kernels.c``) sits beside it.
"""
