"""A guarded XML reader for URDF and SRDF text.

expat builds the tree directly, so the guards run while parsing: a document type
declaration (and with it every entity declaration, the road to entity-expansion bombs and to
external entities) is refused, nesting depth and element count are capped, and so is the
size of the text. Unexpanded xacro is named as such.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from xml.parsers import expat

from ..errors import FieldError, Loc

__all__ = ["parse_xml"]


def parse_xml(data: bytes, loc: Loc, *, what: str, max_bytes: int, max_depth: int,
              max_elements: int) -> ET.Element:
    """The root element of the XML ``data``; ``FieldError(loc, ...)`` when it is too large,
    not well-formed, declares a DOCTYPE or entities, nests too deep or has too many
    elements. ``what`` names the document in messages ("the URDF 'robot.urdf'")."""
    if len(data) > max_bytes:
        raise FieldError(loc, f"{what} is {len(data):,} bytes; at most {max_bytes:,} allowed")
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[ET.Element] = []
    roots: list[ET.Element] = []
    count = 0

    def start(tag: str, attrib: dict[str, str]) -> None:
        nonlocal count
        count += 1
        if count > max_elements:
            raise FieldError(loc, f"{what} has more than {max_elements:,} elements")
        if len(stack) >= max_depth:
            raise FieldError(loc, f"{what} nests elements more than {max_depth} deep "
                                  f"(at <{tag}>, line {parser.CurrentLineNumber})")
        if tag.startswith("xacro:"):
            raise FieldError(loc, f"{what} holds unexpanded xacro (<{tag}>, line "
                                  f"{parser.CurrentLineNumber}): expand it with xacro first")
        element = ET.Element(tag, attrib)
        if stack:
            stack[-1].append(element)
        else:
            roots.append(element)
        stack.append(element)

    def end(tag: str) -> None:
        stack.pop()

    def refuse(*_args) -> None:
        raise FieldError(loc, f"{what} declares a DOCTYPE or entities (line "
                              f"{parser.CurrentLineNumber}); these are not accepted")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    parser.UnparsedEntityDeclHandler = refuse
    parser.ExternalEntityRefHandler = refuse
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise FieldError(loc, f"{what} is not well-formed XML: {expat.ErrorString(exc.code)} "
                              f"(line {exc.lineno}, column {exc.offset + 1})") from None
    if not roots:
        raise FieldError(loc, f"{what} holds no XML element")
    return roots[0]
