"""Text for people: long lists cut to a readable length."""

from __future__ import annotations

from typing import Iterable


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
