"""Reading XML description files with line numbers, and typed access to their elements.

Every malformed value raises DescriptionError naming the file, the element and its line, so
a user sees one line that tells them where to look.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from lxml import etree
from lxml.etree import _Element as Element

from simbot.description.errors import DescriptionError

_PARSER = etree.XMLParser(remove_comments=True, remove_pis=True, resolve_entities=False, no_network=True)


def parse_file(path: Path) -> Element:
    """The root element of an XML file; unreadable or malformed XML is a DescriptionError."""
    try:
        return etree.parse(str(path), _PARSER).getroot()
    except OSError as exc:
        raise DescriptionError(path, f"cannot read file: {exc.strerror or exc}") from None
    except etree.XMLSyntaxError as exc:
        raise DescriptionError(path, f"malformed XML: {exc.msg}", line=exc.lineno) from None


def parse_text(text: str, source: Path | str) -> Element:
    """The root element of XML held in a string (e.g. xacro output)."""
    try:
        return etree.fromstring(text.encode(), _PARSER)
    except etree.XMLSyntaxError as exc:
        raise DescriptionError(source, f"malformed XML: {exc.msg}", line=exc.lineno) from None


def parse_flag(text: str) -> bool | None:
    """An SDF boolean (true/false/1/0), or None when `text` is none of them."""
    return {"1": True, "true": True, "0": False, "false": False}.get(text.strip().lower())


@dataclass(frozen=True)
class Reader:
    """Typed accessors for the elements of one file; errors name that file."""

    file: Path

    def error(self, element: Element, message: str) -> DescriptionError:
        """A DescriptionError pointing at `element`."""
        return DescriptionError(self.file, message, element.tag, element.sourceline)

    def attr(self, element: Element, name: str) -> str:
        """A required attribute."""
        value = element.get(name)
        if value is None or not value.strip():
            raise self.error(element, f"missing required attribute '{name}'")
        return value.strip()

    def child(self, element: Element, tag: str) -> Element:
        """A required child element."""
        found = element.find(tag)
        if found is None:
            raise self.error(element, f"missing required element <{tag}>")
        return found

    def text(self, element: Element, tag: str, default: str | None = None) -> str | None:
        """Stripped text of an optional child element."""
        found = element.find(tag)
        if found is None or found.text is None:
            return default
        return found.text.strip()

    def floats(self, element: Element, count: int | None = None) -> tuple[float, ...]:
        """The whitespace-separated numbers of an element's text."""
        words = (element.text or "").split()
        try:
            values = tuple(float(w) for w in words)
        except ValueError:
            raise self.error(element, f"expected numbers, got {element.text!r}") from None
        if count is not None and len(values) != count:
            raise self.error(element, f"expected {count} numbers, got {len(values)}")
        return values

    def number(self, element: Element, tag: str, default: float) -> float:
        """An optional numeric child element."""
        found = element.find(tag)
        return default if found is None else self.floats(found, 1)[0]

    def required_number(self, element: Element, tag: str) -> float:
        """A required numeric child element."""
        return self.floats(self.child(element, tag), 1)[0]

    def integer(self, element: Element, tag: str, default: int) -> int:
        """An optional integer child element."""
        value = self.number(element, tag, float(default))
        if value != int(value):
            raise self.error(element.find(tag), f"expected a whole number, got {value}")
        return int(value)

    def vector(self, element: Element, tag: str, count: int, default: tuple[float, ...] | None = None) -> tuple[float, ...] | None:
        """An optional child element holding `count` numbers."""
        found = element.find(tag)
        return default if found is None else self.floats(found, count)

    def flag(self, element: Element, tag: str, default: bool) -> bool:
        """An optional boolean child element (true/false/1/0)."""
        value = self.text(element, tag)
        if value is None:
            return default
        flag = parse_flag(value)
        if flag is None:
            raise self.error(element.find(tag), f"expected true or false, got {value!r}")
        return flag
