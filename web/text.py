"""Text that comes from requests, put into the viewer's Markdown so that it shows as written.

The panel's texts are Markdown (viser's ``add_markdown``). Browsers render it with GitHub's
extensions and raw HTML, unsanitised, and viser's server replaces every ``![alt](path)`` in it
by the image file at ``path`` on the server's disk, embedded (code spans included). So any
text a request chose (robot, joint, cylinder, object and scene names, planner names,
messages, job errors, exceptions that quote them) enters that Markdown only through
``plain`` or ``code``; the panel's own words and formatted numbers stay Markdown.

Both put the text on one line: a line break could end the paragraph (or the code span) it
sits in and open a block of its own (a heading, an HTML block, a table).
"""

from __future__ import annotations

import re

__all__ = ["plain", "code", "WORD_JOINER"]

#: Zero-width and invisible: set where GitHub's autolinks would start. remark-gfm finds URLs,
#: ``www.`` and e-mail addresses in the text after escapes are read, so no escape stops them.
WORD_JOINER = "\u2060"
#: ASCII punctuation: CommonMark reads each of these, backslash-escaped, as itself.
_PUNCTUATION = re.compile(r"([!-/:-@\[-`{-~])")
_SPACE = re.compile(r"\s+")
_AUTOLINK = re.compile(r"(?i)(?<=www)(?=\.)|(?<=:)(?=/)|(?<=@)")
_BACKTICKS = re.compile(r"`+")


def _one_line(text: object) -> str:
    return _SPACE.sub(" ", str(text)).strip()


def plain(text: object) -> str:
    """``text`` as Markdown that shows exactly it, on one line: no tag, entity, image, link,
    autolink or emphasis of its own; safe in a table cell."""
    return _PUNCTUATION.sub(r"\\\1", _AUTOLINK.sub(WORD_JOINER, _one_line(text)))


def code(text: object) -> str:
    """``text`` as an inline code span (shown literally, never autolinked), on one line; its
    fence is longer than any run of backticks in it. Not for table cells: a ``|`` splits the
    cell even within a code span."""
    text = _one_line(text).replace("![", f"!{WORD_JOINER}[")  # viser reads those in code too
    fence = "`" * (1 + max((len(run) for run in _BACKTICKS.findall(text)), default=0))
    pad = " " if text[:1] == "`" or text[-1:] == "`" else ""
    return f"{fence}{pad}{text}{pad}{fence}"
