"""A generated block of a document, between two marker comments: written (``--write``) or
compared with a fresh run (``--check``) by the tools that measure it
(``tools/energy_model_terms.py``, ``tools/spring_mechanics.py``,
``tools/adapted_cross_check.py``). The comparison is ``tools/readme_tables.py``'s: identical
words, numbers within a unit of their last printed digit."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def block_span(doc: Path, text: str, begin: str, end: str) -> tuple[int, int]:
    """Start and end offsets of the text between the markers ``begin`` and ``end``."""
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        raise SystemExit(f"{doc}: markers {begin} … {end} not found")
    return i + len(begin), j


def mode_parser(description: str) -> argparse.ArgumentParser:
    """The tools' command line: no option prints, ``--check`` or ``--write``."""
    ap = argparse.ArgumentParser(description=description)
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--check", action="store_true", help="compare with docs; exit 1 on drift")
    g.add_argument("--write", action="store_true", help="rewrite the docs block")
    return ap


def write_or_check(doc: Path, begin: str, end: str, body: str, name: str,
                   write: bool) -> int:
    """Rewrite the block with ``body`` (``write``) or compare it with ``body``: 0 when it is
    current, else 1 with the drifting lines on stderr."""
    from readme_tables import drift_lines, same_at_printed_precision
    text = doc.read_text(encoding="utf-8")
    i, j = block_span(doc, text, begin, end)
    if write:
        doc.write_text(text[:i] + "\n" + body + "\n" + text[j:], encoding="utf-8")
        return 0
    old = text[i:j].strip("\n")
    if same_at_printed_precision(old, body):
        print(f"{name}: current")
        return 0
    print(f"{name}: {doc.name} differs from a fresh run:", file=sys.stderr)
    for ln in drift_lines(old, body):
        print("  " + ln, file=sys.stderr)
    return 1
