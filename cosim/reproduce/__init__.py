"""Reproductions of the source papers (docs/reproductions.md): a plug-in area.

Each module registered under the entry-point group ``ins_cosim.reproductions``
(``pyproject.toml``) offers :class:`cosim.reproductions.Reproduction`::

    DEFAULT_RUNS, DEFAULT_SEED, DEFAULT_CASE
    def reproduce(out_dir: Path, runs: int, seed: int) -> str
    def rerun(case: str, index: int, runs: int, seed: int) -> str

``reproduce`` runs the paper's cases (campaigns included), writes its plots into
``out_dir`` and returns a Markdown block (tables of the paper's figures next to ours, with
the tolerance written next to each number); ``rerun`` runs one run of one case alone, with
the numbers it has in the whole reproduction. ``ins-cosim reproduce NAME`` finds them by
name (:mod:`cosim.reproductions`); nothing else imports this package.
"""
