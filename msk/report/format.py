"""Formatting helpers of the report's sections and the Jinja2 environment of its templates.

The environment autoescapes every value a template prints: a string of ``summary.json`` (a
trial name, a method, an EMG label) is data, shown as written, never markup. Helpers that return
markup (:func:`status_html`, :func:`check`) return :class:`markupsafe.Markup` built with
:meth:`Markup.format`, which escapes what it inserts.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np
from jinja2 import Environment, FileSystemLoader, StrictUndefined
from markupsafe import Markup, escape

from msk.report.references import cite_internal_names
from msk.status import STATUS_MEANING, Status

__all__ = [
    "STATUS_COLOURS",
    "check",
    "environment",
    "esc",
    "escape_text",
    "finite",
    "group_statuses",
    "num",
    "or_",
    "status_html",
    "status_legend",
]

#: Colours of the :mod:`msk.status` words (tables, figures): green = identified (after the
#: colour coding of the segment parameters in Hayashibe et al. 2011, Fig. 3), orange = at a
#: bound, blue = not determined, grey = the prior (generic value kept).
STATUS_COLOURS = {
    Status.IDENTIFIED.value: "#2e7d32",
    Status.AT_BOUND.value: "#ef6c00",
    Status.NOT_DETERMINED.value: "#1e88e5",
    Status.PRIOR.value: "#9e9e9e",
}

TEMPLATES = Path(__file__).with_name("templates")


def esc(x: Any) -> Markup:
    """HTML-escaped text with the literature named instead of internal document names."""
    return escape(cite_internal_names(str(x)))


def finite(x: Any) -> TypeGuard[float]:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def num(x: Any, fmt: str = ".3g", unit: str = "") -> str:
    """``x`` formatted, with its unit; "—" when missing or not finite."""
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "—"
    s = format(x, fmt)
    return f"{s} {unit}".rstrip() if unit else s


def or_(x: Any, default: Any) -> Any:
    """``x``, or ``default`` when the summary does not have it (``None``)."""
    return default if x is None else x


def status_html(word: str) -> Markup:
    """A status word with its colour swatch and its meaning as a tooltip."""
    col = STATUS_COLOURS.get(word, "#9e9e9e")
    return Markup(
        '<span class="status" title="{}"><span class="flag" style="background:{}"></span>{}</span>'
    ).format(STATUS_MEANING.get(word, ""), col, word)


def status_legend() -> Markup:
    return Markup('<p class="note">Status: {}.</p>').format(
        Markup("; ").join(
            Markup("{} — {}").format(status_html(w), m) for w, m in STATUS_MEANING.items()
        )
    )


def check(
    value: Any,
    limit: float,
    *,
    flagged: bool | None = None,
    below: bool = True,
    needs_value: bool = True,
) -> Markup:
    """'ok' / 'over threshold' (or 'below threshold') for a quality figure. ``flagged`` (whether
    the gate of ``summary.quality.flags`` was raised) decides when the run checked it (not
    None); otherwise the value is compared with ``limit``."""
    if needs_value and value is None and not flagged:
        return Markup('<span class="note">not checked</span>')
    if flagged is not None:
        bad = flagged
    elif not finite(value):
        return Markup('<span class="note">not checked</span>')
    else:
        bad = value > limit if below else value < limit
    if not bad:
        return Markup('<span class="ok">✓ ok</span>')
    word = "over threshold" if below else "below threshold"
    return Markup('<span class="bad">⚠ {}</span>').format(word)


def _finalize(x: Any) -> Any:
    if x is None:
        return ""
    if isinstance(x, str) and not isinstance(x, Markup):
        return cite_internal_names(x)
    return x


@functools.cache
def environment() -> Environment:
    """The Jinja2 environment of the report's templates (autoescape on, undefined names an
    error)."""
    env = Environment(
        loader=FileSystemLoader(str(TEMPLATES)),
        autoescape=True,
        undefined=StrictUndefined,
        finalize=_finalize,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=False,
    )
    env.globals.update(num=num, status_html=status_html, status_legend=status_legend)
    return env


def render(template: str, **context: Any) -> str:
    """``template`` (a file of ``msk/report/templates``) rendered with ``context``."""
    return environment().get_template(template).render(**context)


def escape_text(x: Any) -> str:
    """:func:`esc` as a plain string (for text written into SVG or HTML outside a template)."""
    return str(esc(x))


def group_statuses(strength: Any) -> list[str]:
    """The :mod:`msk.status` word of every group of a ``summary.strength`` record
    (:meth:`msk.results.summary.Strength.group_status`)."""
    return [strength.group_status(g) for g in strength.groups]
