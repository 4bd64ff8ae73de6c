"""Strings from input files made safe for the code and markup the exporters generate.

Names (lights, images), `lightcal_version` and warnings come from files a user may not
have written. Whatever reaches generated text goes through one of these, by construction:

- `plain_line`: a header line (IES keyword, EULUMDAT name, OpenCV value): control and
  line-break characters become spaces, blanks collapse, at most `max_chars`.
- `xml_attribute`: an XML attribute value: `plain_line`, quoted (`quoteattr`).
- `xml_comment`: text inside `<!-- -->`: `plain_line`, `&<>` escaped, no `--`.
- `markdown_text`: a name in Markdown: one line, HTML and Markdown syntax shown literally.
- `markdown_prose`: generated prose that may quote names (warnings): one line; `code`
  and *emphasis* stay, HTML, links and images do not.

Python code gets its strings with `repr`, which is a literal by construction.
"""

from __future__ import annotations

import html
import re
from xml.sax.saxutils import escape, quoteattr

__all__ = [
    "MAX_NAME_CHARS",
    "markdown_prose",
    "markdown_text",
    "plain_line",
    "xml_attribute",
    "xml_comment",
]

MAX_NAME_CHARS = 200
"""Longest name written into a header line (IES lines hold 256 characters at most)."""

# C0/C1 controls, DEL, the line and paragraph separators, and what XML 1.0 cannot hold
# (surrogates, U+FFFE/U+FFFF): each one becomes a space.
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\ud800-\udfff\ufffe\uffff]")
_BLANKS = re.compile(r"\s+")
_MARKDOWN_LINKS = re.compile(r"([\\\[\]!])")
# Markdown syntax a name could start: emphasis, code, links and images, tables, strike,
# headings; `_` only at a word's edge (inside a word it is text: view_01); a list or
# numbered-list marker only at the start.
_MARKDOWN_SPECIAL = re.compile(r"([\\`*\[\]!|~#]|(?<![0-9A-Za-z])_|_(?![0-9A-Za-z]))")
_MARKDOWN_LIST_MARKER = re.compile(r"^([-+]|\d+(?=[.)]))")


def plain_line(text: object, *, max_chars: int = MAX_NAME_CHARS) -> str:
    """`text` as one line of printable characters: controls and line breaks become
    spaces, blanks collapse, ends are trimmed; longer than `max_chars`, it is cut and
    ends in '...'."""
    line = _BLANKS.sub(" ", _UNSAFE.sub(" ", str(text))).strip()
    if len(line) > max_chars:
        line = line[: max(max_chars - 3, 0)].rstrip() + "..."
    return line


def xml_attribute(text: object, *, max_chars: int = MAX_NAME_CHARS) -> str:
    """`text` as a quoted XML attribute value (quotes included): `plain_line`, escaped."""
    return quoteattr(plain_line(text, max_chars=max_chars))


def xml_comment(text: object, *, max_chars: int = MAX_NAME_CHARS) -> str:
    """`text` for inside an XML comment: `plain_line`, `&<>` escaped, no `--`, no final `-`."""
    return re.sub(r"-(?=-)", "- ", escape(plain_line(text, max_chars=max_chars))).rstrip("-")


def markdown_text(text: object, *, max_chars: int = 1000) -> str:
    """`text` shown literally in Markdown: one line, no HTML, no links, images or formatting."""
    plain = html.escape(plain_line(text, max_chars=max_chars), quote=False)
    plain = _MARKDOWN_SPECIAL.sub(r"\\\1", plain)
    return _MARKDOWN_LIST_MARKER.sub(
        lambda m: m.group(1) + "\\" if m.group(1)[0].isdigit() else "\\" + m.group(1), plain
    )


def markdown_prose(text: object, *, max_chars: int = 4000) -> str:
    """Generated prose (that may quote names) for one Markdown line: its `code` and
    *emphasis* stay; HTML, links and images are shown literally."""
    return _MARKDOWN_LINKS.sub(
        r"\\\1", html.escape(plain_line(text, max_chars=max_chars), quote=False)
    )
