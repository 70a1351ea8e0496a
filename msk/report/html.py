"""The report page: its sections (:mod:`msk.report.sections`) filled from their Jinja2 templates
into ``templates/page.html.j2`` under a strict Content-Security-Policy, and its printing to PDF
by headless Chromium (see :mod:`msk.report`)."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import tempfile
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

from markupsafe import Markup

from msk._runtime.secure import write_file_atomic
from msk.gait.norms import NormativeBands
from msk.report.figures import build_figures, kinematics_figure, kinetics_figure
from msk.report.format import STATUS_COLOURS, num, render
from msk.report.sections import SECTIONS, ReportContext
from msk.report.sections.mass import weak_direction_words
from msk.results.folder import SessionResults

__all__ = [
    "CONTENT_SECURITY_POLICY",
    "SHIPPED",
    "STATUS_COLOURS",
    "ChromiumSandboxWarning",
    "build_figures",
    "chromium_args",
    "chromium_executable",
    "default_norms",
    "pdf_attempts",
    "render_html",
    "sandbox_possible",
    "weak_direction_words",
    "without_scripts",
    "write_pdf",
    "write_report",
]


#: ``norms=SHIPPED``: the first normative set msk ships (:func:`msk.gait.norms.shipped_norms`)
SHIPPED = "shipped"


def default_norms() -> NormativeBands | None:
    """The first normative set shipped with msk (by name), None when there is none or it cannot
    be read."""
    from msk.exceptions import MskError
    from msk.gait.norms import read_norms, shipped_norms

    files = shipped_norms()
    if not files:
        return None
    try:
        return read_norms(next(iter(files.values())))
    except (MskError, OSError, ValueError):
        return None


def render_html(
    res: SessionResults,
    figures: Mapping[str, str] | None = None,
    *,
    pdf_path: str | Path | None = None,
    norms: NormativeBands | str | None = SHIPPED,
    trials: Sequence[SessionResults] = (),
) -> str:
    """The report as one self-contained HTML string: every section of :data:`SECTIONS` that
    has something for this session, numbered in order, then the references it cited.
    ``pdf_path``: where the printable copy is written (printed in the page's footer);
    ``norms``: normative bands drawn in grey under the gait-cycle grids (:mod:`msk.gait.norms`;
    :data:`SHIPPED`: msk's shipped set, :func:`default_norms`; None: none);
    ``trials``: the results of every task trial of the session (``res`` the first): the gait
    sections pool their cycles and strides (one report per session), the others are ``res``'s."""
    figs = build_figures(res) if figures is None else figures
    s = res.summary
    # a session of FES trials only has no gait results: its report is the FES section
    gait = res.has("q") or not s.fes
    if isinstance(norms, str):
        norms = default_norms() if norms == SHIPPED else None
    ctx = ReportContext(res, figs, gait=gait, norms=norms, trials=tuple(trials))
    pooled = norms is not None or len(trials) > 1
    curves = ctx.curves() if gait and pooled else None
    if curves is not None:  # the grids redrawn: over the bands, with every trial's cycles
        grids = {"kinematics": kinematics_figure(curves, norms),
                 "kinetics": kinetics_figure(curves, norms)}  # fmt: skip
        ctx.figures = {**figs, **{k: v for k, v in grids.items() if v}}
    bodies = [b for b in (sec.render(ctx) for sec in SECTIONS) if b]
    names = [t.summary.trial or "" for t in trials] if len(trials) > 1 else [s.trial or ""]
    if not any(names):
        names = [Path(i.path).stem for i in s.inputs if i.role == "task"]
    return (
        render(
            "page.html.j2",
            csp=Markup(CONTENT_SECURITY_POLICY),
            kind="Gait analysis" if gait else "FES knee model",
            subject=s.subject,
            trials=[n for n in names if n],
            created=s.created_utc,
            version=s.versions.get("msk", ""),
            not_available=s.not_available or (),
            flags=s.quality.flags or (),
            num=num,
            sections=[Markup(b) for b in bodies],
            pdf_path=str(pdf_path) if pdf_path else "",
        )
        + "\n"
    )


def chromium_executable() -> str | None:
    """Path of a headless-capable Chromium/Chrome, or ``None``."""
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        p = shutil.which(name)
        if p:
            return p
    return None


#: what the report's HTML allows: its inline styles and SVG figures and nothing else — no script
#: (the report has none), no frame, no load of any URL (file, network), no form, no base (a
#: string from a data file that slipped past escaping could not run, frame a local file into
#: the PDF or call home)
CONTENT_SECURITY_POLICY = (
    "default-src 'none'; style-src 'unsafe-inline'; img-src data:; font-src data:; "
    "script-src 'none'; object-src 'none'; frame-src 'none'; child-src 'none'; "
    "form-action 'none'; base-uri 'none'"
)
_CSP_META = f'<meta http-equiv="Content-Security-Policy" content="{CONTENT_SECURITY_POLICY}">'


class ChromiumSandboxWarning(UserWarning):
    """report.pdf was printed by Chromium without its sandbox (see :func:`write_pdf`)."""


def sandbox_possible() -> bool:
    """Whether Chromium's sandbox can start here: not as root (Chromium refuses to run as root
    with its sandbox: ``--no-sandbox`` is then the only way)."""
    geteuid = getattr(os, "geteuid", None)
    return geteuid is None or geteuid() != 0


def chromium_args(user_data_dir: str, *, sandbox: bool | None = None) -> list[str]:
    """Headless Chromium's arguments; ``sandbox`` None: with the sandbox unless
    :func:`sandbox_possible` says it cannot start (root), then ``--no-sandbox``."""
    if sandbox is None:
        sandbox = sandbox_possible()
    return [
        "--headless",
        *(() if sandbox else ("--no-sandbox",)),
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-extensions",
        f"--user-data-dir={user_data_dir}",
    ]


def without_scripts(html_text: str) -> str:
    """``html_text`` with the no-script Content-Security-Policy as the first element of its
    head and without ``<meta http-equiv="refresh">`` (Chromium then runs no script of the
    page, loads nothing and does not navigate away, whatever it holds: its
    ``--blink-settings=scriptEnabled=false`` also stops headless printing)."""
    # a refresh/redirect pragma would replace the page before it is printed
    html_text = re.sub(
        r"<meta\b[^>]*http-equiv\s*=\s*[\"']?\s*refresh[^>]*>",
        "",
        html_text,
        flags=re.IGNORECASE,
    )
    m = re.search(r"<head\b[^>]*>", html_text, flags=re.IGNORECASE)
    if m is not None:
        return html_text[: m.end()] + _CSP_META + html_text[m.end() :]
    d = re.match(r"\s*<!doctype[^>]*>", html_text, flags=re.IGNORECASE)
    at = d.end() if d is not None else 0
    return html_text[:at] + f"<head>{_CSP_META}</head>" + html_text[at:]


def pdf_attempts() -> list[bool]:
    """The sandbox settings :func:`write_pdf` tries in order: sandboxed first, unsandboxed
    only as the fallback when the sandbox cannot start (or only that, as root)."""
    return [True, False] if sandbox_possible() else [False]


def write_pdf(html_path: str | Path, pdf_path: str | Path, *, timeout_s: float = 60.0) -> bool:
    """Print ``html_path`` to ``pdf_path`` with headless Chromium; ``False`` if unavailable.

    JavaScript is disabled for the print (the page is printed with a no-script
    Content-Security-Policy, :func:`without_scripts`). Chromium runs with its sandbox; without
    it (``--no-sandbox``) only as root, where the sandbox cannot start, or when a sandboxed
    start fails — and a :class:`ChromiumSandboxWarning` says so."""
    exe = chromium_executable()
    if exe is None:
        return False
    dest = Path(pdf_path)
    dest = dest.parent.resolve() / dest.name  # a symlink at pdf_path is replaced, not followed
    with tempfile.TemporaryDirectory() as work:
        pdf = Path(work) / "report.pdf"  # Chromium prints into this private folder only
        page = Path(work) / "report.html"  # the report is self-contained: no relative links
        page.write_text(
            without_scripts(Path(html_path).read_text(encoding="utf-8")), encoding="utf-8"
        )
        for k, sandbox in enumerate(pdf_attempts()):
            prof = Path(work) / f"profile{k}"
            cmd = [
                exe,
                *chromium_args(str(prof), sandbox=sandbox),
                "--no-pdf-header-footer",
                f"--print-to-pdf={pdf}",
                page.as_uri(),
            ]
            try:
                subprocess.run(cmd, capture_output=True, timeout=timeout_s, check=False)
            except (OSError, subprocess.TimeoutExpired):
                return False
            if pdf.is_file() and pdf.stat().st_size > 0:
                write_file_atomic(dest, pdf.read_bytes())
                if not sandbox:
                    why = (
                        "running as root"
                        if not sandbox_possible()
                        else "its sandbox could not start here"
                    )
                    warnings.warn(
                        f"{dest.name}: Chromium printed without its sandbox ({why}); "
                        "JavaScript was disabled",
                        ChromiumSandboxWarning,
                        stacklevel=2,
                    )
                return True
    return False


def write_report(
    res: SessionResults,
    folder: str | Path,
    *,
    figures: Mapping[str, str] | None = None,
    pdf: bool | None = None,
    norms: NormativeBands | str | None = SHIPPED,
    trials: Sequence[SessionResults] = (),
) -> Path:
    """Write ``report.html`` (and ``report.pdf`` when Chromium is available and ``pdf`` is not
    False; ``MSK_NO_PDF=1`` disables it) into ``folder``; ``norms`` and ``trials`` as for
    :func:`render_html`."""
    folder = Path(folder)
    path = folder / "report.html"
    # a private temporary file renamed into place: a symlink planted in a received folder (as
    # report.html, report.pdf or any temporary name) is replaced, never written through
    if pdf is None:
        pdf = os.environ.get("MSK_NO_PDF", "") not in ("1", "true", "yes")
    pdf = bool(pdf) and chromium_executable() is not None
    figs = build_figures(res) if figures is None else figures
    target = (folder.resolve() / "report.pdf") if pdf else None
    write_file_atomic(
        path, render_html(res, figs, pdf_path=target, norms=norms, trials=trials).encode("utf-8")
    )
    if pdf and not write_pdf(path, folder / "report.pdf"):
        # the page names no PDF that is not there
        write_file_atomic(path, render_html(res, figs, norms=norms, trials=trials).encode("utf-8"))
    if not pdf or not (folder / "report.pdf").is_file():
        # no stale report.pdf of earlier results beside the new report.html
        with contextlib.suppress(FileNotFoundError):
            os.unlink(folder / "report.pdf")
    return path
