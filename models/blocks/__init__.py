"""The model blocks: one module per block class, each a truth or sensor model.

Every module here defines block classes (:class:`cosim.models.block.Block` subclasses)
and nothing else a scenario could not name; what several blocks share lives in the
model library one folder up (:mod:`cosim.models`). :func:`cosim.models.truth_models`
finds the classes. A block's C kernel, where it has one, sits beside its module
(``lever_arm.c`` beside ``lever_arm.py``; the table of kernels: :mod:`cosim.models.native`).
"""
