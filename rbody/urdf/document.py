"""A URDF document as elements that remember their file and line, and the readers of its attribute values;
every error names the file, the line and the element (URDFError)."""

from __future__ import annotations

import math
import os
import xml.parsers.expat
from pathlib import Path

import numpy as np

from rbody.source import SourceElement


class URDFError(ValueError):
    """A URDF document rbody cannot read, or that asks for dynamics rbody does not model (the message names the
    file, the line and the element)."""


class Element(SourceElement):
    """An element of a URDF file (rbody.source.SourceElement) whose errors are URDFErrors."""

    ERROR = URDFError

    def all(self, tag: str) -> list["Element"]:
        return [child for child in self.children if child.tag == tag]

    def one(self, tag: str, *, required: bool = False) -> "Element | None":
        """The only child called `tag` (None when absent and not required); URDFError when repeated or missing."""
        found = self.all(tag)
        if len(found) > 1:
            raise found[1].error(f"<{self.tag}> has {len(found)} <{tag}> elements: expected one")
        if not found and required:
            raise self.error(f"<{self.tag}> needs a <{tag}> element")
        return found[0] if found else None

    def check_children(self, known: dict[str, str | None], notes: list[str]) -> None:
        """Refuse a child element not in `known`; a known child with a note (str) is ignored, the note recorded
        once."""
        for child in self.children:
            if child.tag not in known:
                raise child.error(f"unknown element <{child.tag}> in <{self.tag}> (rbody reads "
                                  f"{', '.join(sorted(known))}; it refuses what it does not know, which could "
                                  "change the dynamics)")
            note = known[child.tag]
            if note and note not in notes:
                notes.append(note)

    def text_attribute(self, key: str) -> str:
        if key not in self.attrib:
            raise self.error(f"<{self.tag}> needs the attribute {key}")
        return self.attrib[key]

    def numbers(self, key: str, count: int, default: tuple[float, ...] | None = None) -> np.ndarray:
        """(count,) finite numbers of attribute `key` (space-separated), or `default` when it is absent."""
        if key not in self.attrib:
            if default is None:
                raise self.error(f"<{self.tag}> needs the attribute {key} ({count} number{'s' * (count > 1)})")
            return np.array(default, dtype=float)
        text = self.attrib[key]
        try:
            values = np.array([float(token) for token in text.split()], dtype=float)
        except ValueError:
            raise self.error(f"{key}={text!r}: expected {count} number{'s' * (count > 1)}") from None
        if values.shape != (count,):
            raise self.error(f"{key}={text!r}: expected {count} number{'s' * (count > 1)}, got {len(values)}")
        if not np.all(np.isfinite(values)):
            raise self.error(f"{key}={text!r}: numbers must be finite")
        return values

    def number(self, key: str, default: float | None = None) -> float:
        return float(self.numbers(key, 1, None if default is None else (default,))[0])


def parse_text(text: str, file: str) -> Element:
    """Elements of one XML document, each with its line (expat); comments and text are dropped. Blank lines before
    an XML declaration are skipped, as urdfdom's TinyXML skips them (expat refuses them); lines keep their numbers."""
    stripped = text.lstrip()
    offset = text[:len(text) - len(stripped)].count("\n") if stripped.startswith("<?xml") else 0
    text = stripped if offset or stripped.startswith("<?xml") else text
    root: list[Element] = []
    stack: list[Element] = []
    parser = xml.parsers.expat.ParserCreate()

    def start(tag, attrib):
        element = Element(tag, dict(attrib), file, parser.CurrentLineNumber + offset)
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(tag):
        stack.pop()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as error:
        raise URDFError(f"{file}, line {error.lineno + offset}, column {error.offset}: malformed XML "
                        f"({xml.parsers.expat.ErrorString(error.code)})") from None
    return root[0]


def read_source(source) -> tuple[Element, Path | None]:
    """The root element of `source` (a path or a URDF XML string) and the file's folder (None for a string)."""
    if isinstance(source, (str, os.PathLike)) and not (isinstance(source, str) and source.lstrip().startswith("<")):
        path = Path(source)
        if not path.is_file():
            raise URDFError(f"source={os.fspath(source)!r}: no such file (give a path to a URDF file or its XML text)")
        return parse_text(path.read_text(), str(path)), path.resolve().parent
    if not isinstance(source, str):
        raise URDFError(f"source={source!r}: expected a path or a URDF XML string")
    return parse_text(source, "<string>"), None


def rpy_quaternion(rpy: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of URDF's roll-pitch-yaw (r, p, y) [rad]: rotations about the FIXED
    axes x by r, then y by p, then z by y, i.e. R = Rz(y) Ry(p) Rx(r) (urdfdom's Rotation::setFromRPY, the
    formula Pinocchio and MuJoCo's "XYZ" extrinsic Euler angles both give)."""
    phi, the, psi = (0.5 * float(a) for a in rpy)
    sr, cr, sp, cp, sy, cy = math.sin(phi), math.cos(phi), math.sin(the), math.cos(the), math.sin(psi), math.cos(psi)
    quat = np.array([cr * cp * cy + sr * sp * sy,
                     sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy])
    return quat / math.sqrt(float(quat @ quat))
