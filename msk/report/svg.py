"""Inline SVG charts of the report, written directly as text: line panels (curves, ± SD bands,
shaded ranges, vertical event lines) in grids, horizontal interval charts and grouped bars.

Every text (titles, axis labels, legend entries — some come from data files) is XML-escaped
here; a chart is a self-contained ``<svg>`` element with a ``viewBox`` that scales to its
container (no script, no external reference: the report's Content-Security-Policy holds). Axis
ticks are the "nice numbers" of Heckbert 1990 (Graphics Gems, "Nice numbers for graph labels"):
steps of 1, 2 or 5 × 10ⁿ.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Bars", "Intervals", "Panel", "grid", "nice_ticks"]

#: font size (px of the viewBox) of tick labels; titles and axis labels are 1–2 px larger
FONT = 11


def _esc(x: object) -> str:
    return html.escape(str(x), quote=True)


def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """About ``n`` round tick values covering [lo, hi] (Heckbert 1990)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else [0.0]
    raw = (hi - lo) / max(n - 1, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0)), key=lambda s: abs(math.log(s / raw)))
    first = math.ceil(lo / step - 1e-9) * step
    ticks = []
    v = first
    while v <= hi + 1e-9 * step:
        ticks.append(0.0 if abs(v) < 1e-12 * step else v)
        v += step
    return ticks


def _fmt(v: float) -> str:
    return f"{v:.10g}" if abs(v) >= 1e-3 or v == 0 else f"{v:.1e}"


def _points(xs: np.ndarray, ys: np.ndarray) -> str:
    return " ".join(f"{x:.1f},{y:.1f}" for x, y in zip(xs, ys))


@dataclass
class _Line:
    x: np.ndarray
    y: np.ndarray
    colour: str
    label: str
    width: float
    dash: str | None


@dataclass
class _Band:
    x: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    colour: str
    opacity: float
    label: str


@dataclass
class Panel:
    """One axes: curves, bands (mean ± SD, a normative range), horizontal spans (a literature
    range) and vertical lines (foot off), with a title and labelled axes."""

    title: str = ""
    xlabel: str = ""
    ylabel: str = ""
    xlim: tuple[float, float] | None = None
    note: str = ""
    lines: list[_Line] = field(default_factory=list)
    bands: list[_Band] = field(default_factory=list)
    spans: list[tuple[float, float, str, str]] = field(default_factory=list)
    vlines: list[tuple[float, str, str]] = field(default_factory=list)

    def line(
        self,
        x: ArrayLike,
        y: ArrayLike,
        colour: str,
        label: str = "",
        *,
        width: float = 1.6,
        dash: str | None = None,
    ) -> Panel:
        self.lines.append(
            _Line(np.asarray(x, float), np.asarray(y, float), colour, label, width, dash)
        )
        return self

    def band(
        self,
        x: ArrayLike,
        lo: ArrayLike,
        hi: ArrayLike,
        colour: str,
        label: str = "",
        *,
        opacity: float = 0.25,
    ) -> Panel:
        self.bands.append(
            _Band(
                np.asarray(x, float),
                np.asarray(lo, float),
                np.asarray(hi, float),
                colour,
                opacity,
                label,
            )
        )
        return self

    def span(self, lo: float, hi: float, colour: str, label: str = "") -> Panel:
        """A horizontal range across the panel (a literature range of the y quantity)."""
        self.spans.append((lo, hi, colour, label))
        return self

    def vline(self, x: float, colour: str, label: str = "") -> Panel:
        self.vlines.append((float(x), colour, label))
        return self

    @property
    def empty(self) -> bool:
        return not any(np.isfinite(ln.y).any() for ln in self.lines)

    def legend(self) -> list[tuple[str, str, str]]:
        """(kind, colour, label) of the labelled items, in drawing order."""
        out = [("band", b.colour, b.label) for b in self.bands if b.label]
        out += [("band", c, lab) for _, _, c, lab in self.spans if lab]
        out += [("line", ln.colour, ln.label) for ln in self.lines if ln.label]
        out += [("vline", c, lab) for _, c, lab in self.vlines if lab]
        return out

    def _limits(self) -> tuple[float, float, float, float]:
        xs = [ln.x[np.isfinite(ln.y)] for ln in self.lines] + [b.x for b in self.bands]
        xs = [x[np.isfinite(x)] for x in xs if x.size]
        ys = [ln.y for ln in self.lines] + [b.lo for b in self.bands] + [b.hi for b in self.bands]
        ys = [y[np.isfinite(y)] for y in ys]
        ys += [np.array([lo, hi]) for lo, hi, _, _ in self.spans]
        xv = np.concatenate(xs) if xs else np.zeros(1)
        yv = np.concatenate([y for y in ys if y.size] or [np.zeros(1)])
        x0, x1 = self.xlim if self.xlim else (float(xv.min()), float(xv.max()))
        y0, y1 = float(yv.min()), float(yv.max())
        if y1 - y0 < 1e-9:
            y0, y1 = y0 - 1.0, y1 + 1.0
        pad = 0.05 * (y1 - y0)
        return x0, (x1 if x1 > x0 else x0 + 1.0), y0 - pad, y1 + pad

    def svg(self, ox: float, oy: float, w: float, h: float) -> str:
        """The panel's elements in a box at (ox, oy) of size w × h (its margins inside)."""
        ml, mr, mt, mb = 46.0, 8.0, 20.0 if self.title else 8.0, 34.0
        pw, ph = w - ml - mr, h - mt - mb
        x0, x1, y0, y1 = self._limits()
        xt, yt = nice_ticks(x0, x1), nice_ticks(y0, y1)
        if self.xlim is None and xt:
            x0, x1 = min(x0, xt[0]), max(x1, xt[-1])

        def px(x: np.ndarray | float) -> np.ndarray:
            return ox + ml + (np.asarray(x, float) - x0) / (x1 - x0) * pw

        def py(y: np.ndarray | float) -> np.ndarray:
            return oy + mt + (y1 - np.asarray(y, float)) / (y1 - y0) * ph

        out = [
            f'<rect x="{ox + ml:.1f}" y="{oy + mt:.1f}" width="{pw:.1f}" height="{ph:.1f}" '
            'fill="#fff" stroke="#888" stroke-width="0.8"/>'
        ]
        for t in yt:
            y = float(py(t))
            out.append(
                f'<line x1="{ox + ml:.1f}" x2="{ox + ml + pw:.1f}" y1="{y:.1f}" '
                f'y2="{y:.1f}" stroke="#e0e0e0" stroke-width="0.6"/>'
                f'<text x="{ox + ml - 4:.1f}" y="{y + 3.5:.1f}" text-anchor="end">'
                f"{_fmt(t)}</text>"
            )
        for t in xt:
            x = float(px(t))
            out.append(
                f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{oy + mt:.1f}" '
                f'y2="{oy + mt + ph:.1f}" stroke="#eeeeee" stroke-width="0.6"/>'
                f'<text x="{x:.1f}" y="{oy + mt + ph + 13:.1f}" text-anchor="middle">'
                f"{_fmt(t)}</text>"
            )
        if y0 < 0 < y1:
            y = float(py(0.0))
            out.append(
                f'<line x1="{ox + ml:.1f}" x2="{ox + ml + pw:.1f}" y1="{y:.1f}" '
                f'y2="{y:.1f}" stroke="#9e9e9e" stroke-width="0.8"/>'
            )
        for lo, hi, colour, _ in self.spans:
            ya, yb = float(py(hi)), float(py(lo))
            out.append(
                f'<rect x="{ox + ml:.1f}" y="{ya:.1f}" width="{pw:.1f}" '
                f'height="{max(yb - ya, 0.5):.1f}" fill="{colour}" '
                'fill-opacity="0.35"/>'
            )
        for b in self.bands:
            ok = np.isfinite(b.lo) & np.isfinite(b.hi) & np.isfinite(b.x)
            if ok.sum() < 2:
                continue
            xs = px(b.x[ok])
            pts = _points(np.r_[xs, xs[::-1]], np.r_[py(b.hi[ok]), py(b.lo[ok])[::-1]])
            out.append(
                f'<polygon points="{pts}" fill="{b.colour}" '
                f'fill-opacity="{b.opacity:g}" stroke="none"/>'
            )
        for x, colour, _ in self.vlines:
            if x0 <= x <= x1:
                xx = float(px(x))
                out.append(
                    f'<line x1="{xx:.1f}" x2="{xx:.1f}" y1="{oy + mt:.1f}" '
                    f'y2="{oy + mt + ph:.1f}" stroke="{colour}" stroke-width="1.1" '
                    'stroke-dasharray="4 3"/>'
                )
        for ln in self.lines:
            ok = np.isfinite(ln.y) & np.isfinite(ln.x)
            # a gap (NaN) splits the curve: one polyline per finite run
            edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(int), 0]))
            dash = f' stroke-dasharray="{ln.dash}"' if ln.dash else ""
            for a, b in zip(edges[::2], edges[1::2]):
                if b - a == 1:
                    out.append(
                        f'<circle cx="{float(px(ln.x[a])):.1f}" '
                        f'cy="{float(py(ln.y[a])):.1f}" r="1.8" fill="{ln.colour}"/>'
                    )
                    continue
                pts = _points(px(ln.x[a:b]), py(ln.y[a:b]))
                out.append(
                    f'<polyline points="{pts}" fill="none" stroke="{ln.colour}" '
                    f'stroke-width="{ln.width:g}"{dash}/>'
                )
        if self.title:
            out.append(
                f'<text x="{ox + ml + pw / 2:.1f}" y="{oy + 13:.1f}" '
                f'text-anchor="middle" font-weight="600" font-size="{FONT + 1}">'
                f"{_esc(self.title)}</text>"
            )
        if self.note:
            out.append(
                f'<text x="{ox + ml + 4:.1f}" y="{oy + mt + 12:.1f}" fill="#555">'
                f"{_esc(self.note)}</text>"
            )
        out.append(
            f'<text x="{ox + ml + pw / 2:.1f}" y="{oy + h - 4:.1f}" '
            f'text-anchor="middle">{_esc(self.xlabel)}</text>'
        )
        cy = oy + mt + ph / 2
        out.append(
            f'<text transform="translate({ox + 11:.1f},{cy:.1f}) rotate(-90)" '
            f'text-anchor="middle">{_esc(self.ylabel)}</text>'
        )
        return "".join(out)


def _svg_open(w: float, h: float, label: str) -> str:
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w:.0f} {h:.0f}" '
        f'width="{w:.0f}" height="{h:.0f}" role="img" aria-label="{_esc(label)}" '
        f'font-family="system-ui,Arial,sans-serif" font-size="{FONT}">'
    )


def _legend_svg(items: Sequence[tuple[str, str, str]], y: float, w: float) -> tuple[str, float]:
    """Legend entries laid out in rows across ``w``; returns (elements, height used)."""
    seen: dict[str, tuple[str, str]] = {}
    for kind, colour, label in items:
        seen.setdefault(label, (kind, colour))
    out, x, row, step = [], 10.0, 0, 16.0
    for label, (kind, colour) in seen.items():
        width = 30 + 6.2 * len(label)
        if x + width > w and x > 10:
            x, row = 10.0, row + 1
        yy = y + row * step
        if kind == "band":
            out.append(
                f'<rect x="{x:.1f}" y="{yy - 8:.1f}" width="18" height="10" '
                f'fill="{colour}" fill-opacity="0.45"/>'
            )
        elif kind == "vline":
            out.append(
                f'<line x1="{x + 9:.1f}" x2="{x + 9:.1f}" y1="{yy - 9:.1f}" '
                f'y2="{yy + 2:.1f}" stroke="{colour}" stroke-dasharray="3 2"/>'
            )
        elif kind == "marker":
            out.append(f'<circle cx="{x + 9:.1f}" cy="{yy - 3:.1f}" r="4" fill="{colour}"/>')
        else:
            out.append(
                f'<line x1="{x:.1f}" x2="{x + 18:.1f}" y1="{yy - 3:.1f}" '
                f'y2="{yy - 3:.1f}" stroke="{colour}" stroke-width="2"/>'
            )
        out.append(f'<text x="{x + 23:.1f}" y="{yy:.1f}">{_esc(label)}</text>')
        x += width
    return "".join(out), (row + 1) * step + 6 if seen else 0.0


def grid(
    panels: Sequence[Panel | None],
    ncols: int,
    *,
    label: str,
    panel_w: float = 250.0,
    panel_h: float = 190.0,
) -> str | None:
    """Panels in rows of ``ncols`` (a None leaves its cell empty) with one shared legend below;
    None when no panel has a curve."""
    if not any(p is not None and not p.empty for p in panels):
        return None
    nrows = -(-len(panels) // ncols)
    w = ncols * panel_w
    body = []
    items: list[tuple[str, str, str]] = []
    for k, p in enumerate(panels):
        if p is None:
            continue
        r, c = divmod(k, ncols)
        body.append(p.svg(c * panel_w, r * panel_h, panel_w, panel_h))
        items += p.legend()
    leg, lh = _legend_svg(items, nrows * panel_h + 14, w)
    h = nrows * panel_h + lh
    return _svg_open(w, h, label) + "".join(body) + leg + "</svg>"


@dataclass
class Intervals:
    """A horizontal chart of one value per row with its interval (strength factors): a marker
    per row coloured by its status, a reference line and a shaded plausible range."""

    rows: Sequence[tuple[str, float | None, float | None, float | None, str, bool]]
    """(row label, value, interval low, interval high, colour, filled marker)"""
    xlabel: str
    xlim: tuple[float, float]
    reference: tuple[float, str] | None = None
    span: tuple[float, float, str] | None = None
    legend: Sequence[tuple[str, str, str]] = ()

    def svg(self, label: str) -> str:
        ml, mr, rh, top = 150.0, 16.0, 20.0, 10.0
        w = 720.0
        pw = w - ml - mr
        ph = rh * len(self.rows)
        x0, x1 = self.xlim

        def px(x: float) -> float:
            return ml + (min(max(x, x0), x1) - x0) / (x1 - x0) * pw

        out = [
            f'<rect x="{ml}" y="{top}" width="{pw:.1f}" height="{ph:.1f}" fill="#fff" '
            'stroke="#888" stroke-width="0.8"/>'
        ]
        if self.span:
            s_lo, s_hi, colour = self.span
            out.append(
                f'<rect x="{px(s_lo):.1f}" y="{top}" width="{px(s_hi) - px(s_lo):.1f}" '
                f'height="{ph:.1f}" fill="{colour}" fill-opacity="0.5"/>'
            )
        for t in nice_ticks(x0, x1, 8):
            x = px(t)
            out.append(
                f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{top}" y2="{top + ph:.1f}" '
                f'stroke="#e0e0e0" stroke-width="0.6"/><text x="{x:.1f}" '
                f'y="{top + ph + 13:.1f}" text-anchor="middle">{_fmt(t)}</text>'
            )
        if self.reference:
            x = px(self.reference[0])
            out.append(
                f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{top}" y2="{top + ph:.1f}" '
                'stroke="#000" stroke-dasharray="4 3"/>'
            )
        for k, (name, value, lo, hi, colour, filled) in enumerate(self.rows):
            y = top + rh * (k + 0.5)
            out.append(f'<text x="{ml - 6}" y="{y + 4:.1f}" text-anchor="end">{_esc(name)}</text>')
            if lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi):
                out.append(
                    f'<line x1="{px(lo):.1f}" x2="{px(hi):.1f}" y1="{y:.1f}" '
                    f'y2="{y:.1f}" stroke="{colour}" stroke-width="1.5"/>'
                )
            if value is not None and math.isfinite(value):
                fill = colour if filled else "#fff"
                out.append(
                    f'<circle cx="{px(value):.1f}" cy="{y:.1f}" r="4.5" fill="{fill}" '
                    f'stroke="{colour}" stroke-width="1.5"/>'
                )
        out.append(
            f'<text x="{ml + pw / 2:.1f}" y="{top + ph + 28:.1f}" '
            f'text-anchor="middle">{_esc(self.xlabel)}</text>'
        )
        items = list(self.legend)
        leg, lh = _legend_svg(items, top + ph + 48, w)
        h = top + ph + 40 + lh
        return _svg_open(w, h, label) + "".join(out) + leg + "</svg>"


@dataclass
class Bars:
    """Grouped vertical bars (segment masses): one group per category, one bar per series,
    optional ± error and per-bar colours, hatched outline-only series."""

    categories: Sequence[str]
    series: Sequence[tuple[str, Sequence[float | None], Sequence[str] | str, Sequence[float]]]
    """(label, values, colour or per-bar colours, error half-widths (may be empty))"""
    ylabel: str
    extra_legend: Sequence[tuple[str, str, str]] = ()

    def svg(self, label: str) -> str:
        ml, mr, top, mb = 56.0, 10.0, 10.0, 78.0
        gw = 52.0
        w = max(720.0, ml + mr + gw * len(self.categories))
        pw = w - ml - mr
        ph = 220.0
        gw = pw / max(len(self.categories), 1)
        vals = [
            (v or 0.0) + (e[k] if len(e) > k else 0.0)
            for _, vs, _, e in self.series
            for k, v in enumerate(vs)
            if v is not None and math.isfinite(v)
        ]
        y1 = max(vals) * 1.08 if vals else 1.0
        ticks = nice_ticks(0.0, y1)
        y1 = max(y1, ticks[-1])

        def py(v: float) -> float:
            return top + ph - v / y1 * ph

        out = [
            f'<rect x="{ml}" y="{top}" width="{pw:.1f}" height="{ph:.1f}" fill="#fff" '
            'stroke="#888" stroke-width="0.8"/>'
        ]
        for t in ticks:
            y = py(t)
            out.append(
                f'<line x1="{ml}" x2="{ml + pw:.1f}" y1="{y:.1f}" y2="{y:.1f}" '
                f'stroke="#e0e0e0" stroke-width="0.6"/><text x="{ml - 4}" '
                f'y="{y + 3.5:.1f}" text-anchor="end">{_fmt(t)}</text>'
            )
        ns = len(self.series)
        bw = gw * 0.8 / max(ns, 1)
        for s, (_, vs, colours, errs) in enumerate(self.series):
            for k, v in enumerate(vs):
                if v is None or not math.isfinite(v):
                    continue
                x = ml + gw * k + gw * 0.1 + bw * s
                col = colours if isinstance(colours, str) else colours[k]
                fill = "#fff" if col == "hatch" else col
                stroke = "#37474f"
                out.append(
                    f'<rect x="{x:.1f}" y="{py(v):.1f}" width="{bw:.1f}" '
                    f'height="{max(py(0) - py(v), 0):.1f}" fill="{fill}" '
                    f'stroke="{stroke}" stroke-width="0.6"'
                    + (' stroke-dasharray="2 1.5"' if col == "hatch" else "")
                    + "/>"
                )
                e = errs[k] if len(errs) > k else 0.0
                if e and math.isfinite(e):
                    xc = x + bw / 2
                    out.append(
                        f'<line x1="{xc:.1f}" x2="{xc:.1f}" y1="{py(v + e):.1f}" '
                        f'y2="{py(max(v - e, 0)):.1f}" stroke="#000" '
                        'stroke-width="0.9"/>'
                    )
        for k, c in enumerate(self.categories):
            x = ml + gw * (k + 0.5)
            y = top + ph + 8
            out.append(
                f'<text transform="translate({x:.1f},{y:.1f}) rotate(-40)" '
                f'text-anchor="end">{_esc(c)}</text>'
            )
        out.append(
            f'<text transform="translate(14,{top + ph / 2:.1f}) rotate(-90)" '
            f'text-anchor="middle">{_esc(self.ylabel)}</text>'
        )
        items = [
            (
                "band",
                "#ffffff"
                if (c if isinstance(c, str) else "") == "hatch"
                else (c if isinstance(c, str) else "#90a4ae"),
                lab,
            )
            for lab, _, c, _ in self.series
        ]
        items += list(self.extra_legend)
        leg, lh = _legend_svg(items, top + ph + mb, w)
        h = top + ph + mb + lh
        return _svg_open(w, h, label) + "".join(out) + leg + "</svg>"
