"""Which files of the site's folder the report owns: ``--out/drivenav-report.json``, its manifest.

A report claims its files before it writes any (:func:`claim`): a file it would write that no earlier report's
manifest lists (an index.html of one's own, an unrelated ``assets/report.css``) is refused with one line, never
overwritten; then the files the earlier manifest lists are removed, so that a report written again replaces its
pages and pictures (a run redone shows its new trajectory, never the old one). The manifest lists both until the
site is written (:func:`settle`), so a report killed half-way leaves no file it does not own. A manifest entry is a
plain relative path (``runs/a/episodes/0.html``): a manifest naming ``../x``, an absolute path or a folder link out
of the site is refused, and nothing outside the folder is ever removed or written.
"""

from __future__ import annotations

import json
from collections.abc import Collection
from pathlib import Path, PurePosixPath

from drivenav.errors import InputError
from drivenav.eval.rundir import inside, write_json_atomic

MANIFEST = "drivenav-report.json"
FORMAT = 1  # the manifest's own format


def claim(out: Path, files: Collection[str]) -> None:
    """Make ``out`` ready for a site of ``files`` (paths relative to it): refuse a file there that no manifest
    lists, or a folder of the site that leads out of ``out``; then remove what the earlier report wrote."""
    previous = owned(out)
    for name in sorted(files):
        target = out / name
        if name not in previous and (target.exists() or target.is_symlink()):
            expected = f"a folder holding only files that drivenav report wrote (listed in {MANIFEST}), or a new one"
            raise InputError(target, "--out", expected, "a file it did not write: remove it or choose another --out")
        if inside(out, str(PurePosixPath(name).parent)) is None:
            raise InputError(target.parent, "--out", "a folder inside the site's folder", "a link out of it")
    _write(out, previous | set(files))
    for name in sorted(previous):
        _remove(out, name)


def settle(out: Path, files: Collection[str]) -> None:
    """Record ``files`` as the site's, once it is written."""
    _write(out, set(files))


def owned(out: Path) -> frozenset[str]:
    """The files the manifest in ``out`` lists (none without one); an :class:`InputError` for a manifest that is not
    what drivenav wrote."""
    path = out / MANIFEST
    if not (path.exists() or path.is_symlink()):
        return frozenset()
    expected = f"the manifest drivenav report writes ({{'format': {FORMAT}, 'files': [paths inside the site]}})"
    if inside(out, MANIFEST) is None or not path.is_file():
        raise InputError(path, MANIFEST, expected, "a link out of the site's folder or no file")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        raise InputError(path, MANIFEST, expected, "no JSON") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("files"), list):
        raise InputError(path, MANIFEST, expected, "another JSON value")
    for entry in data["files"]:
        if not _plain(entry):
            raise InputError(path, "files", "plain paths inside the site's folder", entry)
    return frozenset(data["files"])


def _plain(entry: object) -> bool:
    """Whether a manifest entry is a plain relative path (no ``..``, ``.``, empty part, backslash or NUL)."""
    if not isinstance(entry, str) or not entry or "\\" in entry or "\0" in entry:
        return False
    return all(part not in ("", ".", "..") for part in entry.split("/"))


def _write(out: Path, files: Collection[str]) -> None:
    """Write the manifest (a fresh file renamed over the old one: no link is followed)."""
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / MANIFEST, {"format": FORMAT, "files": sorted(files)})


def _remove(out: Path, name: str) -> None:
    """Remove an owned file (a link itself, never what it points to; nothing below a folder link out of ``out``)
    and the folders it leaves empty."""
    folder = PurePosixPath(name).parent
    target = out / name
    if inside(out, str(folder)) is None or not (target.is_symlink() or target.is_file()):
        return
    target.unlink()
    for parent in (out / folder, *(out / folder).parents):
        if parent == out or not parent.is_relative_to(out):
            return
        try:
            parent.rmdir()
        except OSError:  # not empty
            return
