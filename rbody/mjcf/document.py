"""An MJCF document as elements that remember their file and line, includes expanded, and the readers
of its attribute values; every error names the file, the line and the element (MJCFError)."""

from __future__ import annotations

import os
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


class MJCFError(ValueError):
    """An MJCF document rbody cannot read, or that would change the dynamics in a way rbody does not model."""


# ----- the document as elements with their file and line ------------------------------------------------

@dataclass
class Element:
    tag: str
    attrib: dict
    file: str
    line: int
    children: list = field(default_factory=list)

    def where(self) -> str:
        name = self.attrib.get("name")
        label = f"<{self.tag} name={name!r}>" if name else f"<{self.tag}>"
        return f"{self.file}, line {self.line}, {label}"

    def error(self, message: str) -> MJCFError:
        return MJCFError(f"{self.where()}: {message}")


def parse_text(text: str, file: str) -> Element:
    """Elements of one XML document, each with its line (expat); comments and text are dropped."""
    root: list[Element] = []
    stack: list[Element] = []
    parser = xml.parsers.expat.ParserCreate()

    def start(tag, attrib):
        element = Element(tag, dict(attrib), file, parser.CurrentLineNumber)
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(tag):
        stack.pop()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as error:
        raise MJCFError(f"{file}, line {error.lineno}, column {error.offset}: malformed XML "
                        f"({xml.parsers.expat.ErrorString(error.code)})") from None
    return root[0]


def read_source(source: Any) -> tuple[Element, Path | None]:
    """The root element of `source` (a path or an XML string) and the file's folder (None for a string)."""
    if isinstance(source, (str, os.PathLike)) and not (isinstance(source, str) and source.lstrip().startswith("<")):
        path = Path(source)
        if not path.is_file():
            raise MJCFError(f"source={os.fspath(source)!r}: no such file (give a path to an MJCF file or the XML text)")
        return parse_text(path.read_text(), str(path)), path.resolve().parent
    if not isinstance(source, str):
        raise MJCFError(f"source={source!r}: expected a path or an MJCF XML string")
    return parse_text(source, "<string>"), None


def expand_includes(element: Element, folder: Path, active: tuple[str, ...]) -> None:
    """Replace every <include file> below `element` by the children of the included <mujoco>."""
    expanded = []
    for child in element.children:
        if child.tag != "include":
            expand_includes(child, folder, active)
            expanded.append(child)
            continue
        unknown = set(child.attrib) - {"file"}
        if unknown or "file" not in child.attrib:
            raise child.error("an include needs exactly one attribute, file")
        path = (folder / child.attrib["file"]).resolve()
        if not path.is_file():
            raise child.error(f"included file {str(path)!r} does not exist")
        if str(path) in active:
            raise child.error(f"includes {str(path)!r}, which includes this file again (a cycle)")
        included = parse_text(path.read_text(), str(path))
        if included.tag != "mujoco":
            raise included.error("an included file must have <mujoco> as its root element")
        expand_includes(included, path.parent, active + (str(path),))
        expanded.extend(included.children)
    element.children = expanded


# ----- numbers ------------------------------------------------------------------------------------------

def numbers(element: Element, key: str, attrib: dict, count: int | tuple | None = None) -> np.ndarray:
    text = attrib[key]
    try:
        values = np.array([float(token) for token in text.split()], dtype=float)
    except ValueError:
        raise element.error(f"{key}={text!r}: expected numbers") from None
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


def choice(element: Element, key: str, attrib: dict, choices: tuple, default: str) -> str:
    value = attrib.get(key, default)
    if value not in choices:
        raise element.error(f"{key}={value!r}: expected one of {choices}")
    return value


def boolean(element: Element, key: str, attrib: dict, default: bool) -> bool:
    return choice(element, key, attrib, ("true", "false"), "true" if default else "false") == "true"
