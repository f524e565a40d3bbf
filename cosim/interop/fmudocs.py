"""An FMU's ``documentation/index.html``: its model page (``models/docs/<Model>.md``) as HTML.

FMI 2.0 (section 2.2.1) lets an FMU carry a ``documentation/`` folder whose entry point is
``index.html``. Ours holds the model's own page only, rendered from the Markdown the
project generates (:mod:`cosim.interop.modeldocs`): headings, paragraphs, bullet lists,
tables, fenced code blocks, inline code, emphasis and links. It is the subset those
pages use, not a general Markdown renderer; anything else stays as escaped text.
"""

from __future__ import annotations

import html
import re
from pathlib import Path

_CODE = re.compile(r"`([^`]+)`")
_BOLD = re.compile(r"\*\*([^*]+)\*\*")
_ITALIC = re.compile(r"(?<![*\w])\*([^*\s][^*]*)\*(?![*\w])")
_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
_STYLE = (
    "body{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.4}"
    "pre{background:#f4f4f4;padding:.6em;overflow-x:auto}"
    "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:.2em .5em}"
)


def inline(text: str) -> str:
    """One line of Markdown text as HTML (code spans, bold, italic, links; rest escaped).

    Parameters
    ----------
    text : str
        Markdown text without block structure.

    Returns
    -------
    str
        HTML.
    """
    parts = _CODE.split(text)
    out = []
    for i, part in enumerate(parts):
        if i % 2:
            out.append(f"<code>{html.escape(part)}</code>")
            continue
        part = html.escape(part, quote=False)
        part = _LINK.sub(lambda m: f'<a href="{html.escape(m.group(2))}">{m.group(1)}</a>', part)
        part = _BOLD.sub(r"<strong>\1</strong>", part)
        out.append(_ITALIC.sub(r"<em>\1</em>", part))
    return "".join(out)


def _table(rows: list[str]) -> str:
    cells = [[c.strip() for c in r.strip().strip("|").split("|")] for r in rows]
    body = [r for r in cells[1:] if not all(set(c) <= set(":- ") for c in r)]
    head = "".join(f"<th>{inline(c)}</th>" for c in cells[0])
    lines = "".join("<tr>" + "".join(f"<td>{inline(c)}</td>" for c in r) + "</tr>" for r in body)
    return f"<table><tr>{head}</tr>{lines}</table>"


def markdown_to_html(text: str, title: str) -> str:
    """A whole HTML page from one of the project's Markdown pages.

    Parameters
    ----------
    text : str
        The Markdown source.
    title : str
        The page title.

    Returns
    -------
    str
        A self-contained HTML document (inline style, no scripts, no external files).
    """
    lines = text.splitlines()
    out: list[str] = []
    para: list[str] = []
    i = 0

    def flush() -> None:
        if para:
            out.append(f"<p>{inline(' '.join(para))}</p>")
            para.clear()

    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        if stripped.startswith("```"):
            flush()
            lang = stripped[3:].strip()
            block = []
            i += 1
            while i < len(lines) and not lines[i].strip().startswith("```"):
                block.append(lines[i])
                i += 1
            cls = f' class="language-{html.escape(lang)}"' if lang else ""
            out.append(f"<pre><code{cls}>{html.escape(chr(10).join(block))}</code></pre>")
        elif stripped.startswith("<!--"):
            flush()
            while i < len(lines) and "-->" not in lines[i]:
                i += 1
        elif m := re.match(r"(#{1,6})\s+(.*)", stripped):
            flush()
            level = len(m.group(1))
            out.append(f"<h{level}>{inline(m.group(2))}</h{level}>")
        elif stripped.startswith("|"):
            flush()
            rows = []
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append(lines[i])
                i += 1
            out.append(_table(rows))
            continue
        elif re.match(r"[-*]\s+", stripped):
            flush()
            items = []
            while i < len(lines) and (re.match(r"\s*[-*]\s+", lines[i]) or lines[i][:2] == "  "):
                if re.match(r"\s*[-*]\s+", lines[i]) and not lines[i].startswith("  "):
                    items.append(re.sub(r"^\s*[-*]\s+", "", lines[i]))
                elif items:
                    items[-1] += " " + lines[i].strip()
                i += 1
            out.append("<ul>" + "".join(f"<li>{inline(t)}</li>" for t in items) + "</ul>")
            continue
        elif not stripped:
            flush()
        else:
            para.append(stripped)
        i += 1
    flush()
    body = "\n".join(out)
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head>\n"
        f"<body>\n{body}\n</body></html>\n"
    )


def write_documentation(page: Path, out_dir: Path, title: str) -> Path:
    """Write ``out_dir/index.html`` from a Markdown model page.

    Parameters
    ----------
    page : Path
        ``models/docs/<Model>.md``.
    out_dir : Path
        The FMU's documentation folder being assembled (created if missing).
    title : str
        The page title (the model name).

    Returns
    -------
    Path
        The ``index.html`` written.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    index = out_dir / "index.html"
    index.write_text(markdown_to_html(page.read_text(encoding="utf-8"), title), encoding="utf-8")
    return index
