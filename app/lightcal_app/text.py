"""Text that reaches the page: names escaped for markdown, no server paths in messages.

Names (images, lights, uploaded files) come from users and files: in markdown they are
shown literally (`md`), so an image tag or a link in a name is text, not a request.
Messages (`public`) lose the folders of any absolute path they quote, so a page never
learns where the server keeps its files.
"""

from __future__ import annotations

import html
import re

_MD_SPECIAL = re.compile(r"([\\`*_{}\[\]()#+\-.!|~])")
_MD_LINKS = re.compile(r"([\\\[\]!])")
_ABSOLUTE_PATH = re.compile(r"(?<![\w.~\-/])(?:/[^\s/'\"`]+)+/?")


def md(text: object) -> str:
    """`text` shown literally in markdown: no HTML, no formatting, one line."""
    plain = html.escape(" ".join(str(text).split()), quote=False)
    return _MD_SPECIAL.sub(r"\\\1", plain)


def md_prose(text: object) -> str:
    """Generated prose (that may quote names) for markdown: its `code` and *emphasis*
    stay, HTML, links and images do not."""
    return _MD_LINKS.sub(r"\\\1", html.escape(str(text), quote=False))


def public(text: str) -> str:
    """`text` with every absolute path cut to its last part ('/srv/x/a.png' -> 'a.png')."""
    return _ABSOLUTE_PATH.sub(lambda m: m.group(0).rstrip("/").rsplit("/", 1)[-1], text)
