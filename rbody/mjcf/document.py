"""An MJCF document as elements that remember their file and line, includes expanded, and the readers
of its attribute values; every error names the file, the line and the element (MJCFError)."""

from __future__ import annotations

import codecs
import os
import re
import xml.parsers.expat
from pathlib import Path
from typing import Any

import numpy as np

from rbody.source import SourceElement

from rbody.mjcf.grammar import GrammarError, parse_values

MESSAGE_VALUE_LIMIT = 200  # characters of a quoted value a message shows (a 5 MB attribute is never echoed whole)
# a quoted value: its opening quote not just after a letter or digit (the closing quote of another quoted word)
_QUOTED = re.compile(r"""(?<!\w)(?:'[^'\n]{%d,}'|"[^"\n]{%d,}")""" % (MESSAGE_VALUE_LIMIT, MESSAGE_VALUE_LIMIT))


class MJCFError(ValueError):
    """An MJCF document rbody cannot read, or that would change the dynamics in a way rbody does not model.
    A quoted value longer than MESSAGE_VALUE_LIMIT characters in the message is cut, with its length said."""

    def __init__(self, message: str = "") -> None:
        super().__init__(_QUOTED.sub(_cut, str(message)))


def _cut(match: re.Match) -> str:
    text = match.group(0)
    return f"{text[:60]}...{text[0]} ({len(text) - 2} characters)"


# ----- the document as elements with their file and line ------------------------------------------------

class Element(SourceElement):
    """An element of an MJCF file (rbody.source.SourceElement) whose errors are MJCFErrors."""

    ERROR = MJCFError


# MuJoCo's XML parser (tinyxml2) stops at TINYXML2_MAX_ELEMENT_DEPTH = 500 levels of parsing: measured on MuJoCo,
# an element with content may sit at most at level 498 (the root <mujoco> at 1), an empty one (<x/>) at 499.
DEPTH_WITH_CONTENT = 498
DEPTH_EMPTY = 499


def parse_text(text: str, file: str) -> Element:
    """Elements of one XML document, each with its line (expat, which keeps no recursion of its own); comments and
    text are dropped. Nesting deeper than MuJoCo's parser reads (DEPTH_WITH_CONTENT, DEPTH_EMPTY) is an MJCFError,
    as MuJoCo's "XML parse error 18"."""
    root: list[Element] = []
    stack: list[Element] = []
    data = text.encode("utf-8", "surrogatepass")
    parser = xml.parsers.expat.ParserCreate("utf-8")  # the bytes are UTF-8 whatever a declaration says (tinyxml2)

    def start(tag, attrib):
        element = Element(tag, dict(attrib), file, parser.CurrentLineNumber)
        if len(stack) + 1 > DEPTH_EMPTY:
            raise MJCFError(f"{element.where()}: nested {len(stack) + 1} levels deep, beyond the {DEPTH_EMPTY} levels "
                            "MuJoCo's XML parser reads (tinyxml2's depth limit)")
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(tag):
        element = stack.pop()
        at = parser.CurrentByteIndex
        empty = not element.children and data[at - 2:at] == b"/>"  # <x/>: its end event comes right after "/>"
        if len(stack) + 1 > DEPTH_WITH_CONTENT and not empty:
            raise MJCFError(f"{element.where()}: an element with content {len(stack) + 1} levels deep, beyond the "
                            f"{DEPTH_WITH_CONTENT} levels MuJoCo's XML parser reads (tinyxml2's depth limit)")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as error:
        raise MJCFError(f"{file}, line {error.lineno}, column {error.offset}: malformed XML "
                        f"({xml.parsers.expat.ErrorString(error.code)})") from None
    if not root:
        raise MJCFError(f"{file}: no XML element found")
    return root[0]


# ----- bytes as MuJoCo reads them -------------------------------------------------------------------------------
# MuJoCo hands a file's bytes to tinyxml2 as a C string: it ends at the first NUL byte; any other byte is kept as
# it is, whatever an XML declaration says, in comments, text and attribute values alike (a Latin-1 comment is
# skipped, a Latin-1 name is a name, a Latin-1 byte in a number is a bad number); C0 control characters pass too.
# Python's expat wants valid Unicode without control characters, so each byte that is not valid UTF-8, and each
# C0 control character but tab, newline and carriage return, is read as a character of Unicode's private use
# area (U+F700 + the byte): it stays distinct from every other character, is carried through comments and
# values as MuJoCo carries the byte, and can never be a digit, a name start or a space.
_PRIVATE_BYTE = 0xF700
_CONTROL = re.compile("[\x01-\x08\x0b\x0c\x0e-\x1f]")


def _bytes_as_private_use(error: UnicodeDecodeError):
    bad = error.object[error.start:error.end]
    return "".join(chr(_PRIVATE_BYTE + b) for b in bad), error.end


codecs.register_error("rbody-mjcf-bytes", _bytes_as_private_use)


def decode_like_mujoco(data: bytes) -> str:
    """The text of an MJCF file's bytes as MuJoCo reads them (above): up to the first NUL, UTF-8 where valid,
    every other byte and every C0 control character but tab, newline and carriage return kept as U+F700 + byte."""
    data = data.split(b"\0", 1)[0]
    text = data.decode("utf-8", "rbody-mjcf-bytes")
    return _controls_as_private_use(text)


def _controls_as_private_use(text: str) -> str:
    return _CONTROL.sub(lambda m: chr(_PRIVATE_BYTE + ord(m.group(0))), text.split("\0", 1)[0])


def read_source(source: Any) -> tuple[Element, Path | None]:
    """The root element of `source` (a path or an XML string) and the file's folder (None for a string); a file's
    bytes decoded as MuJoCo reads them (decode_like_mujoco)."""
    if isinstance(source, (str, os.PathLike)) and not (isinstance(source, str) and source.lstrip().startswith("<")):
        path = Path(source)
        if not path.is_file():
            raise MJCFError(f"source={os.fspath(source)!r}: no such file (give a path to an MJCF file or the XML text)")
        return parse_text(_read_bytes(path), str(path)), path.resolve().parent
    if not isinstance(source, str):
        raise MJCFError(f"source={source!r}: expected a path or an MJCF XML string")
    return parse_text(_controls_as_private_use(source), "<string>"), None


def _read_bytes(path: Path, element: "Element | None" = None) -> str:
    try:
        data = path.read_bytes()
    except OSError as error:
        where = f"{element.where()}: " if element is not None else ""
        raise MJCFError(f"{where}cannot read {str(path)!r} ({error.strerror or error})") from None
    return decode_like_mujoco(data)


def expand_includes(element: Element, folder: Path, active: tuple[str, ...]) -> None:
    """Replace every <include file> below `element` by the children of the included <mujoco>, as MuJoCo's
    IncludeXML does (src/xml/xml.cc): relative to the including file's folder; a file included twice anywhere in
    the model, an include with children, or an included file without elements is an MJCFError, as in MuJoCo. An
    explicit stack of (element, folder) pairs: no recursion, whatever the nesting."""
    included: set[str] = set(active)
    pending = [(element, folder)]
    while pending:
        parent, here = pending.pop()
        queue = [(child, here) for child in parent.children]  # each child with the folder its includes start from
        expanded = []
        while queue:
            child, where = queue.pop(0)
            if child.tag != "include":
                pending.append((child, where))
                expanded.append(child)
                continue
            unknown = set(child.attrib) - {"file"}
            if unknown or "file" not in child.attrib:
                raise child.error("an include needs exactly one attribute, file")
            if child.children:
                raise child.error("an include element cannot have children (MuJoCo's rule)")
            path = (where / child.attrib["file"]).resolve()
            if not path.is_file():
                raise child.error(f"included file {str(path)!r} does not exist")
            if str(path) in included:
                raise child.error(f"file {str(path)!r} is already included in this model (MuJoCo includes a file once: "
                                  "a second include of it, or one that includes it again, is refused)")
            included.add(str(path))
            document = parse_text(_read_bytes(path, child), str(path))
            if document.tag != "mujoco":
                raise document.error("an included file must have <mujoco> as its root element")
            if not document.children:
                raise child.error(f"included file {str(path)!r} has no elements (MuJoCo: empty include file)")
            queue[0:0] = [(included_child, path.parent) for included_child in document.children]
        parent.children = expanded


# ----- numbers ------------------------------------------------------------------------------------------

def numbers(element: Element, key: str, attrib: dict, count: int | tuple | None = None) -> np.ndarray:
    """The doubles of attribute `key`, read as MuJoCo reads them (rbody.mjcf.grammar: C's strtod, no '1_0', no
    non-ASCII digits, hex accepted), checked finite and, when given, of `count` (an int or a tuple of ints)."""
    text = attrib[key]
    try:
        values = np.array(parse_values(text, "double"), dtype=float)
    except GrammarError as error:
        raise element.error(f"{key}: {error}") from None
    counts = (count,) if isinstance(count, int) else count
    if counts is not None and len(values) not in counts:
        raise element.error(f"{key}={text!r}: expected {' or '.join(map(str, counts))} numbers, got {len(values)}")
    if not np.all(np.isfinite(values)):
        raise element.error(f"{key}={text!r}: numbers must be finite")
    return values


def number(element: Element, key: str, attrib: dict, default: float) -> float:
    if key not in attrib:
        return default
    return float(numbers(element, key, attrib, 1)[0])


def integer(element: Element, key: str, attrib: dict, default: int) -> int:
    """Attribute `key` as MuJoCo reads an int (C's strtol in base 10: '0.9', '1e0' and '0x1' are refused)."""
    if key not in attrib:
        return default
    try:
        values = parse_values(attrib[key], "int")
    except GrammarError as error:
        raise element.error(f"{key}: {error}") from None
    if len(values) != 1:
        raise element.error(f"{key}={attrib[key]!r}: expected one whole number, got {len(values)}")
    return values[0]


def integers(element: Element, key: str, attrib: dict, count: int) -> list[int]:
    """Attribute `key` as `count` ints, read as MuJoCo reads them (integer)."""
    try:
        values = parse_values(attrib[key], "int")
    except GrammarError as error:
        raise element.error(f"{key}: {error}") from None
    if len(values) != count:
        raise element.error(f"{key}={attrib[key]!r}: expected {count} whole numbers, got {len(values)}")
    return values


def choice(element: Element, key: str, attrib: dict, choices: tuple, default: str) -> str:
    value = attrib.get(key, default)
    if value not in choices:
        raise element.error(f"{key}={value!r}: expected one of {choices}")
    return value


def boolean(element: Element, key: str, attrib: dict, default: bool) -> bool:
    return choice(element, key, attrib, ("true", "false"), "true" if default else "false") == "true"
