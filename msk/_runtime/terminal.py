"""Text from data files made safe for a terminal.

Labels, event names, subject names and error messages come from files msk did not write. A
control character in them (ESC starting an ANSI sequence that clears the screen or retitles
the window, BEL, a carriage return that overwrites the line, a C1 control such as CSI U+009B,
a bidirectional override that reverses what follows) must not reach the terminal as such:
:func:`terminal_safe` shows each as a visible escape (``\\x1b``, ``\\u202e``).
"""

from __future__ import annotations

import unicodedata

__all__ = ["terminal_safe"]


def _escape(ch: str) -> str:
    o = ord(ch)
    return f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}" if o < 0x10000 else f"\\U{o:08x}"


def terminal_safe(text: str, *, keep_newline: bool = False) -> str:
    """``text`` with every control (Unicode category Cc: C0, DEL, C1) and format character
    (Cf: bidirectional overrides, zero-width joiners…) escaped; with ``keep_newline`` the line
    feeds stay (the caller's own line structure)."""
    out = []
    for ch in text:
        if keep_newline and ch == "\n":
            out.append(ch)
        elif unicodedata.category(ch) in ("Cc", "Cf"):
            out.append(_escape(ch))
        else:
            out.append(ch)
    return "".join(out)
