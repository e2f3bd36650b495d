"""An element of a model file (MJCF, URDF) that remembers its file and line, so that every error names them."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class SourceElement:
    """An XML element: tag, attributes, the file and line it was read from, its child elements in order.
    `error` builds the reader's own error class (ERROR, a ValueError) with "file, line N, <tag name='...'>: "
    before the message."""

    tag: str
    attrib: dict
    file: str
    line: int
    children: list = field(default_factory=list)

    ERROR = ValueError  # each format's reader names its own (MJCFError, URDFError)

    def where(self) -> str:
        name = self.attrib.get("name")
        label = f"<{self.tag} name={name!r}>" if name else f"<{self.tag}>"
        return f"{self.file}, line {self.line}, {label}"

    def error(self, message: str) -> ValueError:
        return self.ERROR(f"{self.where()}: {message}")
