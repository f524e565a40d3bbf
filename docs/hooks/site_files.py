"""mkdocs hook: pages that live outside docs/ join the site without a copy.

The model pages are generated next to the models (``python -m cosim.interop.modeldocs``
writes ``models/docs/<Model>.md``, which also ship as package data) and the changelog sits
at the repository root; both are added to the site as ``models/<Model>.md`` and
``changelog.md``, so a link from a page resolves and ``mkdocs build --strict`` checks it.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[2]


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add ``models/docs/*.md`` as ``models/*.md`` and ``CHANGELOG.md`` as ``changelog.md``."""
    for page in sorted((ROOT / "models" / "docs").glob("*.md")):
        files.append(File.generated(config, f"models/{page.name}", abs_src_path=str(page)))
    files.append(File.generated(config, "changelog.md", abs_src_path=str(ROOT / "CHANGELOG.md")))
    return files
