"""Reading XML description files with line numbers, and typed access to their elements.

Every malformed value raises DescriptionError naming the file, the element and its line, so
a user sees one line that tells them where to look.

SDF files are read as Gazebo's parser reads them, which is looser than XML: `--` inside a
comment, namespace prefixes that are never declared (`gz:policies`, `experimental:params`) and
element names scoped with `::` (`gz::system_priority`) are accepted. The text is rewritten
before parsing, on the same lines, so line numbers stay those of the file; `sdf_tag` gives an
element's name as the file wrote it.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

from lxml import etree
from lxml.etree import _Element as Element

from simbot.description.errors import DescriptionError

logger = logging.getLogger(__name__)

_PARSER = etree.XMLParser(remove_comments=True, remove_pis=True, resolve_entities=False, no_network=True)

SCOPE_MARK = "\u00b7\u00b7"
"""Stands for `::` in an element name while lxml holds it (a middle dot is a legal name character)."""
UNDECLARED_NS = "urn:simbot:undeclared:"
"""The namespace given to a prefix the file uses but never declares."""

_COMMENT_OR_CDATA = re.compile(r"<!\[CDATA\[.*?\]\]>|<!--(.*?)-->", re.DOTALL)
_SCOPED_TAG = re.compile(r"(</?[A-Za-z_][\w.\-]*)::(?=[A-Za-z_])")
_PREFIXED_NAME = re.compile(r"(?:</?|\s)([A-Za-z_][\w.\-]*):[A-Za-z_][\w.\-]*")
_ROOT_START = re.compile(r"<(?![?!/])[A-Za-z_][\w.:\-]*")


def parse_file(path: Path) -> Element:
    """The root element of an XML file; unreadable or malformed XML is a DescriptionError."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise DescriptionError(path, f"cannot read file: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return _parse(data, path)  # another encoding, declared in the file: lxml reads it, strictly
    return _parse(as_gazebo_reads(text, path).encode("utf-8"), path)


def parse_text(text: str, source: Path | str) -> Element:
    """The root element of XML held in a string (e.g. xacro output), read strictly."""
    return _parse(text.encode("utf-8"), source)


def _parse(data: bytes, source: Path | str) -> Element:
    try:
        return etree.fromstring(data, _PARSER)
    except etree.XMLSyntaxError as exc:
        raise DescriptionError(source, f"malformed XML: {exc.msg}", line=exc.lineno) from None


def as_gazebo_reads(text: str, source: Path | str) -> str:
    """`text` with what Gazebo accepts and XML does not made legal, line numbers unchanged."""
    text = _COMMENT_OR_CDATA.sub(lambda m: _blank_comment(m, source, text), text)
    if _SCOPED_TAG.search(text):
        logger.debug("%s: element names with '::' read as written", source)
        text = _SCOPED_TAG.sub(lambda m: m.group(1) + SCOPE_MARK, text)
    return _declare_prefixes(text, source)


def _blank_comment(match: re.Match[str], source: Path | str, text: str) -> str:
    """A comment holding `--` becomes an empty one (comments are dropped anyway); CDATA stays."""
    body = match.group(1)
    if body is None or "--" not in body:
        return match.group(0)
    logger.debug("%s:%d: a comment holds '--'; read as Gazebo reads it", source, text.count("\n", 0, match.start()) + 1)
    return "<!--" + "\n" * body.count("\n") + "-->"


def _declare_prefixes(text: str, source: Path | str) -> str:
    """Declares, on the root element, every namespace prefix used but never declared."""
    used = {m.group(1) for m in _PREFIXED_NAME.finditer(text)} - {"xml", "xmlns"}
    undeclared = sorted(p for p in used if f"xmlns:{p}=" not in text)
    root = _ROOT_START.search(text)
    if not undeclared or root is None:
        return text
    logger.debug(
        "%s: undeclared namespace prefixes %s; their elements are kept, simbot reads none",
        source,
        ", ".join(undeclared),
    )
    declarations = "".join(f' xmlns:{p}="{UNDECLARED_NS}{p}"' for p in undeclared)
    return text[: root.end()] + declarations + text[root.end() :]


def sdf_tag(element: Element) -> str:
    """The element's name as the file wrote it: `gz:policies`, `gz::system_priority`, `link`."""
    qname = etree.QName(element)
    prefix = (
        qname.namespace[len(UNDECLARED_NS) :] + ":"
        if qname.namespace and qname.namespace.startswith(UNDECLARED_NS)
        else ""
    )
    return prefix + qname.localname.replace(SCOPE_MARK, "::")


def parse_flag(text: str) -> bool | None:
    """An SDF boolean (true/false/1/0), or None when `text` is none of them."""
    return {"1": True, "true": True, "0": False, "false": False}.get(text.strip().lower())


@dataclass(frozen=True)
class Reader:
    """Typed accessors for the elements of one file; errors name that file."""

    file: Path

    def error(self, element: Element, message: str) -> DescriptionError:
        """A DescriptionError pointing at `element`."""
        return DescriptionError(self.file, message, sdf_tag(element), element.sourceline)

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

    def vector(
        self, element: Element, tag: str, count: int, default: tuple[float, ...] | None = None
    ) -> tuple[float, ...] | None:
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
