"""Text from data (a table's name, an id) made safe to embed in an exported file.

A name is data, never markup: it is written as a Python string literal (:func:`literal`,
``repr``), which escapes the backslash, every control character, lone surrogates (the bytes of
a non-UTF-8 file name) and the non-characters U+FFFE/U+FFFF. What remains are printable
characters that XML 1.0, strict JSON and UTF-8 can all hold. Inside an XML comment a ``-``
after a ``-`` is written ``\\x2d`` as well (XML 1.0 §2.5: a comment cannot contain ``--`` and
has no escapes of its own), so the comment cannot end early and stays well-formed; the literal
still reads back as the name (``ast.literal_eval``). Attribute values are escaped by
``xml.sax.saxutils.quoteattr``; characters XML cannot hold at all are refused there.
"""

from __future__ import annotations

import re
from xml.sax.saxutils import quoteattr

#: Characters outside XML 1.0's ``Char`` production (§2.2).
_NOT_XML_CHAR = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")
_SURROGATE = re.compile("[\ud800-\udfff]")


def literal(text, *, comment: bool = False) -> str:
    """``text`` as a Python string literal (``repr``); with ``comment=True`` also without
    ``--`` (each second ``-`` written ``\\x2d``), for an XML comment."""
    out = repr(str(text))
    if comment:
        out = re.sub("(?<=-)-", r"\\x2d", out)
    return out


def unicode_text(text: str, what: str) -> str:
    """``text`` unchanged; ``ValueError`` naming ``what`` where it holds a lone surrogate (a
    string no UTF-8 file, hence no glTF or JSON document, can carry)."""
    bad = _SURROGATE.search(text)
    if bad:
        raise ValueError(f"{what} {text!r} holds the lone surrogate {bad.group()!r}, which "
                         f"UTF-8 cannot carry; use printable characters")
    return text


def xml_comment(text: str) -> str:
    """``<!-- text -->``; ``ValueError`` where ``text`` would not stay one comment (build it
    from :func:`literal` with ``comment=True`` for anything that comes from data)."""
    if "--" in text or text.endswith("-") or _NOT_XML_CHAR.search(text):
        raise ValueError(f"{text!r} cannot be an XML comment: it contains '--', ends with '-' "
                         f"or holds a character XML cannot; pass names through literal()")
    return f"<!-- {text} -->"


def xml_attribute(text: str, what: str) -> str:
    """``text`` quoted and escaped as an XML attribute value; ``ValueError`` naming ``what``
    where it holds a character XML 1.0 cannot (a control character, a lone surrogate)."""
    bad = _NOT_XML_CHAR.search(text)
    if bad:
        raise ValueError(f"{what} {text!r} holds {bad.group()!r}, which XML cannot carry; "
                         f"use printable characters")
    return quoteattr(text)
