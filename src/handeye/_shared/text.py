"""Text for people: long lists cut to a readable length, values quoted in messages kept short."""

from __future__ import annotations

import reprlib
from typing import Iterable

#: How a value read from a user's file is quoted in a message: a few items per level, two levels,
#: strings cut; bounded in time and length whatever the value (a YAML alias bomb, a 10 MB string).
_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxtuple, _SHORT.maxdict = 2, 5, 5, 4
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlong = 60, 60, 40


def cut(text: str, limit: int = 160) -> str:
    """``text`` as it is when short, else its start and end around ``...`` (``limit`` characters in
    all): a file name or a line from a user's file, quoted in a message."""
    text = str(text)
    return text if len(text) <= limit else f"{text[:limit // 2 - 2]}...{text[-(limit // 2 - 1):]}"


def shown(value: object) -> str:
    """``repr(value)`` for a message, at most a line long (:mod:`reprlib`: ``[1, 2, 3, 4, 5, 6, ...]``,
    ``'abcd...wxyz'``): a value from a user's file is quoted, never a screen of it."""
    return _SHORT.repr(value)


def summarize(items: Iterable[object], shown: int = 5) -> str:
    """``items`` as ``'a, b, c, d, e and 4,495 more'``: a list of thousands of ids never fills a
    screen (or one line of an error message)."""
    items = [str(i) for i in items]
    if len(items) <= shown + 1:
        return ", ".join(items)
    return f"{', '.join(items[:shown])} and {len(items) - shown:,} more"


def sentences(parts: Iterable[str]) -> str:
    """Sentences of advice (written without a closing full stop, to be listed one per line) as one
    paragraph: each ended with a full stop unless it has its own."""
    done = [p.strip() for p in parts if p.strip()]
    done = [p[0].upper() + p[1:] if p[0].islower() else p for p in done]
    return " ".join(p if p.endswith((".", "!", "?")) else p + "." for p in done)
