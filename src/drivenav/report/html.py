"""Small HTML writers shared by the report's pages: escaping, elements, tables and the page frame.

Every page is HTML5 with its styles and script beside it in the site (``assets/``): no server and no network, so
the site opens from a file path. Tables are plain ``<table>`` elements, readable without JavaScript; the script
only adds sorting and filtering on top (progressive enhancement).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from html import escape

ASSETS = "assets"
STYLE = "report.css"
SCRIPT = "report.js"
Attributes = dict[str, str | None]


def esc(text: object) -> str:
    """``text`` as HTML text or attribute value (quotes escaped)."""
    return escape(str(text), quote=True)


def attributes(attrs: Attributes) -> str:
    """`` name="value"`` for each attribute; ``None`` values are left out, ``""`` is a bare boolean attribute."""
    parts = [
        f" {name}" if value == "" else f' {name}="{esc(value)}"' for name, value in attrs.items() if value is not None
    ]
    return "".join(parts)


def element(name: str, content: str = "", attrs: Attributes | None = None) -> str:
    """``<name attrs>content</name>`` (``content`` is HTML already)."""
    return f"<{name}{attributes(attrs or {})}>{content}</{name}>"


def void(name: str, attrs: Attributes) -> str:
    """An element without content or end tag (``input``, ``img``, ``meta``)."""
    return f"<{name}{attributes(attrs)}>"


def link(href: str, text: str, attrs: Attributes | None = None) -> str:
    return element("a", esc(text), {"href": href, **(attrs or {})})


@dataclass(frozen=True)
class Cell:
    """A table cell: its HTML and, for sorting, the value it sorts by (None: its text)."""

    html: str
    sort: str | None = None


def table(header: Sequence[str], rows: Iterable[Sequence[Cell | str]], attrs: Attributes | None = None) -> str:
    """A table with a header row of ``header`` (plain text) and body rows (``str`` cells are plain text)."""
    head = "".join(element("th", esc(name), {"scope": "col"}) for name in header)
    body = "".join(_row(row) for row in rows)
    return element("table", f"<thead><tr>{head}</tr></thead><tbody>{body}</tbody>", attrs)


def _row(cells: Sequence[Cell | str], attrs: Attributes | None = None) -> str:
    return element("tr", "".join(_cell(cell) for cell in cells), attrs)


def row(cells: Sequence[Cell | str], attrs: Attributes | None = None) -> str:
    """One ``<tr>`` (for tables whose rows carry attributes)."""
    return _row(cells, attrs)


def _cell(cell: Cell | str) -> str:
    if isinstance(cell, str):
        return element("td", esc(cell))
    return element("td", cell.html, {"data-sort": cell.sort})


def page(title: str, body: str, root: str, script: bool = False) -> str:
    """A whole page: ``root`` is the relative path from the page to the site's folder ("" or "../../")."""
    head = (
        '<meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{esc(title)}</title>"
        f'<link rel="stylesheet" href="{esc(root)}{ASSETS}/{STYLE}">'
    )
    if script:
        head += f'<script src="{esc(root)}{ASSETS}/{SCRIPT}" defer></script>'
    nav = element(
        "nav",
        " · ".join(
            (
                link(f"{root}index.html", "runs"),
                link(f"{root}episodes.html", "episodes"),
                link(f"{root}pivot.html", "pivot"),
            )
        ),
        {"aria-label": "report"},
    )
    return f'<!DOCTYPE html>\n<html lang="en"><head>{head}</head><body>{nav}<main>{body}</main></body></html>\n'
