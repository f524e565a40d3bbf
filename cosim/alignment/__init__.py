"""Alignment-filter blocks: Python blocks in the same protocol as the truth models.

They derive from :class:`models.block.Block` and run in-process (scenario key
``model = "<ClassName>"``, looked up here after ``models/``). They are not packed into
FMUs by ``make fmus``: they are the system under test, not truth models.
"""

from __future__ import annotations

from models import find_blocks
from models.block import Block


def registry() -> dict[str, type[Block]]:
    """All alignment-filter block classes in this package, by class name."""
    return find_blocks(__name__, __path__)
