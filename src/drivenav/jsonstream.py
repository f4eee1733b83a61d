"""Reading JSON documents with bounded work: whole (small files) or one top-level array's items at a time.

:func:`read_document` turns a plain or gzip-compressed file into Python values. An episode file of 100,000
HM3D-style episodes is about 650 MB of JSON: held whole that way it is some 6 GB of objects and two minutes of
parsing before the first episode runs. :class:`ArrayStream` reads such a file as a window of text and hands out the
items of one array of the top-level object one at a time, keeping the object's other members. The text of one
chosen member of the items (an episode's ``goals``, which every episode of a scene and category repeats
verbatim) is decoded and converted once; a later verbatim copy is the same converted object.

Both refuse a document past :data:`MAX_DOCUMENT_BYTES` before reading further (a gzip stream is unpacked only that
far), nested too deep to parse, not UTF-8 or not JSON, and an object that holds a key twice (which JSON readers
settle differently: Python's keeps the last value, a streaming reader may act on the first), each with one
:class:`~drivenav.errors.InputError` naming the file (and a syntax error's line and column, or the repeated key).
A UTF-8 byte order mark before the document is skipped (RFC 8259 lets a reader ignore it). Reading takes time in
proportion to the text, whitespace included: a window that holds only whitespace read already is emptied before more
is read, so a decompression bomb of whitespace reaches its refusal at the limit in seconds.
"""

from __future__ import annotations

import codecs
import gzip
import json
import re
import secrets
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol

from drivenav.errors import InputError

JsonObject = dict[str, Any]
"""A JSON object as ``json.loads`` returns it or ``json.dumps`` takes it. Only the JSON edges use it -- reading and
writing files and wire messages -- and hand typed records to the rest of the code."""

DOCUMENT = "<document>"  # the field of errors about a whole file
MAX_DOCUMENT_BYTES = 1 << 30  # a JSON document after decompression (100,000 HM3D-style episodes: about 650 MB)
CHUNK_BYTES = 1 << 20  # bytes read at a time; a value longer than the window doubles it
SPLICE_REACH = 4096  # characters of an item before and after its repeated member that the fast path reads
MAX_REPEATS = 4096  # distinct member texts remembered for reuse (scenes x categories of a large benchmark)
_GZIP_MAGIC = b"\x1f\x8b"
_ENCODING = "utf-8-sig"  # UTF-8, a leading byte order mark skipped
Decode = Callable[[str, int], tuple[Any, int]]  # a JSON text and a position -> the value there and its end


class _RepeatedKeyError(Exception):
    """An object of the text holds ``key`` twice (raised inside the scanner; not a ValueError, which the window
    reads as text that may go on)."""

    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _unique_keys(pairs: list[tuple[str, Any]]) -> JsonObject:
    """A decoded object's members as a dict, or :class:`_RepeatedKeyError` for the first key it holds twice."""
    members = dict(pairs)
    if len(members) < len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _RepeatedKeyError(key)
            seen.add(key)
    return members


def _repeated_key_error(path: Path, field: str, key: str) -> InputError:
    return InputError(path, field, "each key once in a JSON object", f"'{key}' twice")


_SCAN: Decode = json.JSONDecoder(object_pairs_hook=_unique_keys).scan_once  # type: ignore[attr-defined]  # C scanner
_WHITESPACE = re.compile(r"[ \t\n\r]*")  # JSON's whitespace
_scanstring: Callable[[str, int], tuple[str, int]] = json.decoder.scanstring  # type: ignore[attr-defined]


def _after_space(text: str, pos: int) -> int:
    """The position of the first character at or after ``pos`` that is no JSON whitespace."""
    match = _WHITESPACE.match(text, pos)
    return match.end() if match else pos


Convert = Callable[[Any, int], Any]  # a decoded member value and the index of its item -> what the caller keeps


def _limit_error(path: Path) -> InputError:
    return InputError(path, DOCUMENT, f"at most {MAX_DOCUMENT_BYTES >> 20} MiB of JSON (after decompression)", "more")


@contextmanager
def _document_errors(path: Path) -> Iterator[None]:
    """Reading and decoding faults of ``path`` as one :class:`InputError` each."""
    try:
        yield
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:  # BadGzipFile is an OSError: before that clause
        raise InputError(path, DOCUMENT, "gzip-compressed JSON (a complete gzip stream)", str(exc)) from None
    except OSError as exc:
        raise InputError(path, DOCUMENT, "a readable file", exc.strerror or str(exc)) from None
    except UnicodeDecodeError as exc:
        raise InputError(path, DOCUMENT, "UTF-8 text", str(exc)) from None
    except RecursionError:
        raise InputError(path, DOCUMENT, "JSON nested less deeply", "nesting past Python's recursion limit") from None


class _Bytes(Protocol):
    def read(self, size: int = -1, /) -> bytes: ...


@contextmanager
def _open_bytes(path: Path) -> Iterator[_Bytes]:
    """The file's bytes, unpacked if it is gzip-compressed (recognised by its first bytes)."""
    with path.open("rb") as handle:
        compressed = handle.read(2) == _GZIP_MAGIC
        handle.seek(0)
        if not compressed:
            yield handle
            return
        with gzip.GzipFile(fileobj=handle) as unpacked:
            yield unpacked


def _syntax_error(
    path: Path, message: str, text: str, pos: int, line_base: int = 0, column_base: int = 0
) -> InputError:
    """A JSON syntax error at ``text[pos]``; ``text`` starts at line ``line_base`` (0-based), column ``column_base``
    of the file."""
    newlines = text.count("\n", 0, pos)
    column = pos - text.rfind("\n", 0, pos) if newlines else column_base + pos + 1
    return InputError(path, DOCUMENT, "valid JSON", f"{message} at line {line_base + newlines + 1}, column {column}")


def read_document(path: Path) -> Any:
    """The JSON content of a whole file (see the module docstring for what is refused)."""
    with _document_errors(path), _open_bytes(path) as stream:
        raw = stream.read(MAX_DOCUMENT_BYTES + 1)
        if len(raw) > MAX_DOCUMENT_BYTES:
            raise _limit_error(path)
        text = raw.decode(_ENCODING)
        try:
            return json.loads(text, object_pairs_hook=_unique_keys)
        except json.JSONDecodeError as exc:
            raise _syntax_error(path, exc.msg, text, exc.pos) from None
        except _RepeatedKeyError as exc:
            raise _repeated_key_error(path, DOCUMENT, exc.key) from None


class _Window:
    """A document's text from some point on: ``text[pos:]`` is unread; more is read on demand."""

    def __init__(self, path: Path, stream: _Bytes) -> None:
        self.path = path
        self._stream = stream
        self._decoder = codecs.getincrementaldecoder(_ENCODING)()
        self._bytes = 0
        self.text = ""
        self.pos = 0
        self.eof = False
        self._line_base = 0  # lines and columns of the text dropped before ``text``
        self._column_base = 0

    def more(self) -> bool:
        """Read at least as much again as is unread (at least :data:`CHUNK_BYTES`); False at the end."""
        if self.eof:
            return False
        data = self._stream.read(max(CHUNK_BYTES, len(self.text) - self.pos))
        self._bytes += len(data)
        if self._bytes > MAX_DOCUMENT_BYTES:
            raise _limit_error(self.path)
        self.eof = not data
        self.text += self._decoder.decode(data, final=self.eof)
        return not self.eof

    def drop_read(self) -> None:
        """Forget the text already read once it is a chunk or more (so the window stays about one chunk)."""
        if self.pos >= CHUNK_BYTES:
            self._forget_read()

    def _forget_read(self) -> None:
        newlines = self.text.count("\n", 0, self.pos)
        last_line = self.text.rfind("\n", 0, self.pos) + 1 if newlines else -self._column_base
        self._column_base = self.pos - last_line
        self._line_base += newlines
        self.text, self.pos = self.text[self.pos :], 0

    def skip_space(self) -> str:
        """Skip whitespace; the next character, or '' at the end of the document. Whitespace read is forgotten
        before more is read, so a long run of it costs time in proportion to its length."""
        while True:
            self.pos = _after_space(self.text, self.pos)
            if self.pos < len(self.text):
                return self.text[self.pos]
            self._forget_read()
            if not self.more():
                return ""

    def take(self, char: str) -> bool:
        """Consume ``char`` if it comes next (after whitespace)."""
        found = self.skip_space() == char
        self.pos += found
        return found

    def value(self, decode: Decode = _SCAN) -> Any:
        """Decode the value that comes next, reading more text while it may be incomplete."""
        self.skip_space()
        while True:
            try:
                value, end = decode(self.text, self.pos)
            except StopIteration as stop:
                if not self.more():
                    raise self.error("Expecting value", stop.value) from None
                continue
            except json.JSONDecodeError as exc:
                if not self.more():
                    raise self.error(exc.msg, exc.pos) from None
                continue
            if end < len(self.text) or not self.more():  # a number at the window's end may go on
                self.pos = end
                return value

    def error(self, message: str, pos: int | None = None) -> InputError:
        where = self.pos if pos is None else pos
        return _syntax_error(self.path, message, self.text, where, self._line_base, self._column_base)


class _RepeatedMember:
    """Decodes JSON objects whose member ``key`` repeats verbatim across items (an array or object): a repeat is
    the object ``convert`` made of its first copy, and its text is not decoded again."""

    def __init__(self, key: str, convert: Convert) -> None:
        self.key = key
        self.convert = convert
        self.index = 0  # of the item being decoded, for ``convert``'s error messages
        self._key_text = json.dumps(key) + ":"
        self._stand_in = json.dumps(f"{key}-{secrets.token_hex(16)}")  # no file holds it: it marks the splice
        self._seen: dict[str, list[tuple[str, Any]]] = {}  # the text's first 64 characters -> (text, converted)
        self._count = 0

    def decode(self, text: str, pos: int) -> tuple[Any, int]:
        """The item at ``text[pos]`` and its end: a repeat of the member's text is cut out and the rest decoded by
        the C scanner in one call, else the item is decoded member by member."""
        at = text.find(self._key_text, pos, pos + SPLICE_REACH)
        start = at + len(self._key_text)
        repeat = self._repeat_at(text, start) if at > pos else None
        if repeat is not None:
            seen, converted = repeat
            rest = start + len(seen)
            spliced = text[pos:start] + self._stand_in + text[rest : rest + SPLICE_REACH]
            try:
                item, end = _SCAN(spliced, 0)
            except (StopIteration, json.JSONDecodeError):
                item, end = None, 0
            inside = start - pos + len(self._stand_in) < end < len(spliced)
            if inside and isinstance(item, dict) and item.get(self.key) == self._stand_in[1:-1]:
                item[self.key] = converted
                return item, end - len(self._stand_in) + len(seen) + pos
        return self._members(text, pos)

    def _members(self, text: str, pos: int) -> tuple[Any, int]:
        if not text.startswith("{", pos):
            return _SCAN(text, pos)
        item: JsonObject = {}
        pos = _after_space(text, pos + 1)
        if text.startswith("}", pos):
            return item, pos + 1
        while True:
            if not text.startswith('"', pos):
                raise json.JSONDecodeError("Expecting property name enclosed in double quotes", text, pos)
            name, pos = _scanstring(text, pos + 1)
            if name in item:
                raise _RepeatedKeyError(name)
            pos = _after_space(text, pos)
            if not text.startswith(":", pos):
                raise json.JSONDecodeError("Expecting ':' delimiter", text, pos)
            pos = _after_space(text, pos + 1)
            item[name], pos = self._member(text, pos) if name == self.key else _SCAN(text, pos)
            pos = _after_space(text, pos)
            if text.startswith("}", pos):
                return item, pos + 1
            if not text.startswith(",", pos):
                raise json.JSONDecodeError("Expecting ',' delimiter", text, pos)
            pos = _after_space(text, pos + 1)

    def _repeat_at(self, text: str, pos: int) -> tuple[str, Any] | None:
        for seen, converted in self._seen.get(text[pos : pos + 64], ()):
            if text.startswith(seen, pos):  # an array or object ends where its text ends: the same value
                return seen, converted
        return None

    def _member(self, text: str, pos: int) -> tuple[Any, int]:
        repeat = self._repeat_at(text, pos)
        if repeat is not None:
            return repeat[1], pos + len(repeat[0])
        value, end = _SCAN(text, pos)
        if end == len(text):  # the window may end inside the value (a number): decoded again with more text
            return value, end
        converted = self.convert(value, self.index)
        if text.startswith(("[", "{"), pos) and self._count < MAX_REPEATS:
            self._seen.setdefault(text[pos : pos + 64], []).append((text[pos:end], converted))
            self._count += 1
        return converted, end


class ArrayStream:
    """The items of the array ``key`` of a document's top-level object, one at a time (see the module docstring).

    After :meth:`items` is exhausted, ``members`` holds the object's other members, ``found`` whether ``key`` was
    there, and ``document`` the whole value when the top level is no JSON object (the caller's type check names
    it). With ``member``, each item's member of that name is passed through ``convert`` (the decoded value and the
    item's index) and a verbatim repeat is the first conversion's object.
    """

    def __init__(self, path: Path, key: str, member: str = "", convert: Convert = lambda value, _: value) -> None:
        self.path = path
        self.key = key
        self.members: JsonObject = {}
        self.found = False
        self.document: Any = None
        self._items = _RepeatedMember(member, convert) if member else None

    def items(self) -> Iterator[Any]:
        with _document_errors(self.path), _open_bytes(self.path) as stream:
            window = _Window(self.path, stream)
            if window.skip_space() != "{":
                self.document = self._value(window, DOCUMENT)
            else:
                window.pos += 1
                yield from self._members(window)
            if window.skip_space():
                raise window.error("Extra data")

    def _members(self, window: _Window) -> Iterator[Any]:
        if window.take("}"):
            return
        while True:
            if window.skip_space() != '"':
                raise window.error("Expecting property name enclosed in double quotes")
            name = window.value()
            if not window.take(":"):
                raise window.error("Expecting ':' delimiter")
            if name in self.members or (name == self.key and self.found):
                raise InputError(self.path, name, f"one '{name}' key", "two")
            if name == self.key and window.skip_space() == "[":
                self.found = True
                window.pos += 1
                yield from self._array(window)
            else:
                self.members[name] = self._value(window, name)
            if window.take("}"):
                return
            if not window.take(","):
                raise window.error("Expecting ',' delimiter")

    def _array(self, window: _Window) -> Iterator[Any]:
        if window.take("]"):
            return
        decode = self._items.decode if self._items is not None else _SCAN
        index = 0
        while True:
            if self._items is not None:
                self._items.index = index
            yield self._value(window, f"{self.key}[{index}]", decode)
            window.drop_read()
            index += 1
            if window.take("]"):
                return
            if not window.take(","):
                raise window.error("Expecting ',' delimiter")

    def _value(self, window: _Window, field: str, decode: Decode = _SCAN) -> Any:
        """The value that comes next; an object in it holding a key twice is an error on ``field``."""
        try:
            return window.value(decode)
        except _RepeatedKeyError as exc:
            raise _repeated_key_error(self.path, field, exc.key) from None
