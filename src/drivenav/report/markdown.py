"""The subset of Markdown that ``ablations.md`` is written in, as HTML: headings, paragraphs, lists, pipe tables
and inline code. The report shows the paper's tables exactly as
:func:`drivenav.analysis.ablation_report.format_markdown` writes them, rather than deriving them a second time."""

from __future__ import annotations

import re

from drivenav.report.html import element, esc

_CODE = re.compile(r"`([^`]*)`")
_SEPARATOR = re.compile(r"^\|(\s*:?-+:?\s*\|)+$")


def inline(text: str) -> str:
    """Text with ``code`` spans, escaped."""
    parts = _CODE.split(text)
    return "".join(element("code", esc(part)) if k % 2 else esc(part) for k, part in enumerate(parts))


def _cells(line: str) -> list[str]:
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def _table(lines: list[str]) -> str:
    head = "".join(element("th", inline(cell), {"scope": "col"}) for cell in _cells(lines[0]))
    body = "".join(element("tr", "".join(element("td", inline(cell)) for cell in _cells(line))) for line in lines[2:])
    return element("table", f"<thead><tr>{head}</tr></thead><tbody>{body}</tbody>")


def _block(lines: list[str], heading_shift: int) -> str:
    first = lines[0]
    if first.startswith("#"):
        level = min(6, len(first) - len(first.lstrip("#")) + heading_shift)
        return element(f"h{level}", inline(first.lstrip("#").strip()))
    if first.startswith("|") and len(lines) > 1 and _SEPARATOR.match(lines[1].replace(" ", "")):
        return _table(lines)
    if all(line.startswith("- ") for line in lines):
        return element("ul", "".join(element("li", inline(line[2:])) for line in lines))
    return element("p", inline(" ".join(line.strip() for line in lines)))


def sections(markdown: str) -> list[tuple[str, list[list[str]]]]:
    """The document's ``##`` sections: (title, blocks of lines); the text before the first one has title ""."""
    found: list[tuple[str, list[list[str]]]] = [("", [])]
    for block in (b.splitlines() for b in re.split(r"\n\s*\n", markdown.strip())):
        if block and block[0].startswith("## "):
            found.append((block[0][3:].strip(), []))
        found[-1][1].append(block)
    return found


def to_html(markdown: str, heading_shift: int = 0, leave_out: frozenset[str] = frozenset()) -> str:
    """The document as HTML (headings ``heading_shift`` levels lower), without the ``##`` sections named in
    ``leave_out``."""
    kept = [block for title, blocks in sections(markdown) if title not in leave_out for block in blocks]
    return "\n".join(_block(block, heading_shift) for block in kept if block)
