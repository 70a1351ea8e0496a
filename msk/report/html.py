"""HTML report and its figures (see :mod:`msk.report`)."""

from __future__ import annotations

import contextlib
import html
import io
import os
import re
import shutil
import subprocess
import tempfile
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

from msk._runtime.secure import write_file_atomic
from msk.results.folder import SessionResults
from msk.results.summary import Strength, Summary
from msk.status import (
    FES_DETERMINED_BY_PROTOCOL,
    FES_NRMSD_MAX_PCT,
    STATUS_MEANING,
    STRENGTH_R2_MIN,
    Status,
    fes_status,
    gain_status,
)

__all__ = ["build_figures", "chromium_executable", "render_html", "write_pdf", "write_report"]

#: The literature the report cites, by number ([1] … in the text). Authors are given where the
#: copy of the paper we hold names them; the others are cited by title.
REFERENCES: tuple[str, ...] = (
    "Hayashibe M, Venture G, Ayusawa K, Nakamura Y. Muscle strength and mass distribution "
    "identification toward subject-specific musculoskeletal modeling.",
    "Experimental parameter identification of a multi-scale musculoskeletal model controlled "
    "by electrical stimulation: application to patients with spinal cord injury.",
    "Using subject-specific muscle parameters to compare muscle forces and activation between "
    "an EMG-driven and OpenSim musculoskeletal model (master's thesis).",
    "A computationally efficient musculoskeletal model of the lower limb for the control of "
    "rehabilitation robots: assumptions and validation.",
    "Hicks JL, Uchida TK, Seth A, Rajagopal A, Delp SL (2015). Is my model good enough? Best "
    "practices for verification and validation of musculoskeletal models and simulations of "
    "movement. J Biomech Eng 137:020905.",
    "Delp SL, Loan JP, Hoy MG, Zajac FE, Topp EL, Rosen JM (1990). An interactive graphics-based "
    "model of the lower extremity to study orthopaedic surgical procedures. IEEE Trans Biomed "
    "Eng 37:757–767.",
    "Dumas R, Chèze L, Verriest JP (2007). Adjustments to McConville et al. and Young et al. body "
    "segment inertial parameters. J Biomech 40:543–553.",
)
#: Colours of the :mod:`msk.status` words (tables, figures): green = identified (after the
#: colour coding of the segment parameters in [1], Fig. 3), orange = at a bound, blue = not
#: determined, grey = the prior (generic value kept).
STATUS_COLOURS = {
    Status.IDENTIFIED.value: "#2e7d32",
    Status.AT_BOUND.value: "#ef6c00",
    Status.NOT_DETERMINED.value: "#1e88e5",
    Status.PRIOR.value: "#9e9e9e",
}
#: Kept for callers of the former name (identifiability flags): the status colours.
FLAG_COLOURS = STATUS_COLOURS
#: Plausible strength-factor range (× generic F_iso), thesis [3], Table 3.1.
LITERATURE_FACTOR_RANGE = (0.5, 2.0)
#: (coordinate stem, title, sign): gait2392's knee_angle is negative in flexion; the report shows
#: flexion positive (and the knee moment and power with the same sign change; power unchanged).
_JOINTS = (
    ("hip_flexion", "Hip flexion", 1.0),
    ("knee_angle", "Knee flexion", -1.0),
    ("ankle_angle", "Ankle dorsiflexion", 1.0),
)


# ---------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------
class _Figures:
    """``plt.subplots`` without pyplot: plain :class:`matplotlib.figure.Figure` objects, outside
    pyplot's registry (nothing to close) and without its import (~20 ms) or a GUI backend."""

    @staticmethod
    def subplots(
        nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], **kw: Any
    ) -> tuple[Any, Any]:
        from matplotlib.figure import Figure

        fig = Figure(figsize=figsize)
        return fig, fig.subplots(nrows, ncols, **kw)


def _plt() -> _Figures:
    import matplotlib

    matplotlib.rcParams.update(
        {
            "font.size": 9,
            "svg.fonttype": "none",
            "axes.grid": True,
            "grid.alpha": 0.3,
            # labels come from data files (EMG channels, muscles): a "$" is text, not mathtext
            "text.usetex": False,
            "text.parse_math": False,
        }
    )
    return _Figures()


def _svg(fig: Any, *, laid_out: bool = False) -> str:
    """The figure as SVG text. ``laid_out``: ``tight_layout`` already fitted it to its canvas,
    so no ``bbox_inches="tight"`` (which draws the whole figure once more to measure it)."""
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches=None if laid_out else "tight")
    text = buf.getvalue()
    text = re.sub(r"<metadata>.*?</metadata>\s*", "", text, flags=re.S)  # dates, licence URIs
    return text[text.index("<svg") :]


def _cycle_axis(res: SessionResults, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """x values in % of the gait cycle (from the C3D foot strikes) and the in-cycle mask."""
    cyc = res.summary.gait_cycle_s
    if cyc:
        x = 100.0 * (t - cyc[0]) / (cyc[1] - cyc[0])
        return x, (x >= 0) & (x <= 100), "gait cycle (%)"
    return t, np.ones(t.size, dtype=bool), "time (s)"


def _side(res: SessionResults) -> str:
    return "_l" if res.summary.subject.side == "left" else "_r"


def _fig_strength(res: SessionResults) -> str | None:
    st = res.summary.strength
    if not st or not st.groups:
        return None
    plt = _plt()
    groups = st.groups
    fig, ax = plt.subplots(figsize=(7.5, 0.35 * len(groups) + 1.4))
    y = np.arange(len(groups))
    lo, hi = LITERATURE_FACTOR_RANGE
    ax.axvspan(lo, hi, color="#e3f2fd", label=f"plausible range {lo}–{hi} × [3]")
    ax.axvline(1.0, color="k", lw=1, ls="--", label="generic model (1.0 ×)")
    marker = {"identified": "o", "at bound": "D", "not determined": "o", "prior": "s"}
    for k, g in enumerate(groups):
        f = float("nan") if g.factor is None else g.factor
        status = st.group_status(g)
        col = STATUS_COLOURS[status]
        lab = f"{status}, 95 % CI" if status in ("identified", "not determined") else status
        if _finite(g.ci_low) and _finite(g.ci_high) and status != "prior":
            ax.errorbar(
                f,
                k,
                # an interval end one rounding step past the factor must not abort the figure
                xerr=[[max(0.0, f - g.ci_low)], [max(0.0, g.ci_high - f)]],
                fmt=marker[status],
                color=col,
                mfc=col if status == "identified" else "white",
                capsize=3,
                label=lab,
            )
        else:
            ax.plot(f, k, marker[status], color=col, label=lab)
    ax.set_yticks(y, [g.group for g in groups])
    ax.set_xlabel("strength factor (× generic F_iso, dimensionless)")
    ax.set_ylabel("muscle group (EMG channel)")
    ax.set_xlim(0.3, 2.2)
    handles, labels = ax.get_legend_handles_labels()
    uniq = dict(zip(labels, handles))
    ax.legend(uniq.values(), uniq.keys(), loc="lower right", fontsize=7)
    return _svg(fig)


def _fig_strength_curves(res: SessionResults) -> str | None:
    """Maximal isometric moment–angle curves per action (N·m/kg): generic vs identified; the
    identified curve is drawn only when its status is ``identified``."""
    st = res.summary.strength
    js = st.joint_strength if st else None
    acts = (js.actions if js else None) or ()
    mass = js.mass_kg if js else None
    if not acts or not isinstance(mass, (int, float)) or not np.isfinite(mass) or mass <= 0:
        return None
    plt = _plt()
    ncol = min(4, len(acts))
    nrow = -(-len(acts) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.6 * ncol, 2.3 * nrow), squeeze=False)
    for ax in axes.ravel()[len(acts) :]:
        ax.set_visible(False)
    for ax, a in zip(axes.ravel(), acts):
        x = np.asarray(a.angles_deg, dtype=float)
        ax.plot(x, np.asarray(a.generic_nm, dtype=float) / mass, "k--", lw=1.2,
                label="generic model")  # fmt: skip
        word = a.status or "prior"
        if word == "identified":
            ax.plot(x, np.asarray(a.identified_nm, dtype=float) / mass, lw=1.8,
                    color=STATUS_COLOURS[word], label="identified (this subject)")  # fmt: skip
        else:
            text = "= generic (prior)" if word == "prior" else f"identified: {word}"
            ax.text(0.03, 0.05, text, transform=ax.transAxes, fontsize=7,
                    color=STATUS_COLOURS.get(word, "#9e9e9e"))  # fmt: skip
        ax.set_title(a.action, fontsize=9)
        ax.set_xlabel(f"{a.angle_label} (deg)")
        ax.set_ylabel("moment (N·m/kg)")
        ax.set_ylim(bottom=0.0)
    handles, labels = [], []
    for ax in axes.ravel()[: len(acts)]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8,
               bbox_to_anchor=(0.5, 0.0))  # fmt: skip
    fig.tight_layout(rect=(0, 0.3 / fig.get_figheight(), 1, 1))  # 0.3 in for the legend
    return _svg(fig, laid_out=True)


def _fig_mass(res: SessionResults) -> str | None:
    ident = res.summary.identification
    if not ident:
        return None
    plt = _plt()
    segs = ident.segments
    anth = _anthropometry_masses(res.summary)
    fig, ax = plt.subplots(figsize=(7.5, 3.2))
    x = np.arange(len(segs))
    w = 0.27
    prior = [s.prior_mass_kg for s in segs]
    mass = [s.mass_kg for s in segs]
    err = [2 * (s.mass_std_kg or 0.0) for s in segs]
    cols = [STATUS_COLOURS[s.status_word()] for s in segs]
    ax.bar(x - w, prior, w, color="#cfd8dc", edgecolor="k", lw=0.5, label="scaled generic model")
    ax.bar(
        x,
        mass,
        w,
        color=cols,
        edgecolor="k",
        lw=0.5,
        yerr=err,
        capsize=2,
        label="estimated (±2 SD), coloured by status",
    )
    tab = []
    for s in segs:
        n = s.name
        key = n
        if n.startswith(("talus", "calcn", "toes")):
            key = "foot" + n[-2:]
        elif n.startswith("femur"):
            key = "femur" + n[-2:]
        v = anth.get(key) if n.startswith(("pelvis", "femur", "tibia", "torso", "calcn")) else None
        tab.append(np.nan if v is None else v)
    ax.bar(
        x + w,
        tab,
        w,
        color="white",
        edgecolor="#37474f",
        hatch="//",
        lw=0.5,
        label="anthropometric table (Dumas 2007)",
    )
    for word, col in STATUS_COLOURS.items():
        ax.bar([0], [0], color=col, label=f"status: {word}")
    ax.set_xticks(x, [s.name for s in segs], rotation=40, ha="right")

    ax.set_ylabel("segment mass (kg)")
    ax.set_xlabel("segment")
    ax.legend(fontsize=7, ncol=2)
    return _svg(fig)


def _series(res: SessionResults, table: str, cols: Sequence[str]) -> dict[str, np.ndarray]:
    if not res.has(table):
        return {}
    tb = res.table(table)
    return {c: tb.column(c) for c in cols if c in tb.columns}


def _fig_joints(res: SessionResults) -> str | None:
    if not res.has("q"):
        return None
    plt = _plt()
    sfx = _side(res)
    q = res.table("q")
    x, sel, xl = _cycle_axis(res, q.time)
    tq = res.table("joint_torques") if res.has("joint_torques") else None
    mass = res.summary.subject.mass_kg or 1.0
    fig, axes = plt.subplots(3, 3, figsize=(8.5, 6.5), sharex=True)
    dt = np.gradient(q.time) if q.time.size > 1 else np.ones(1)
    for j, (stem, title, sign) in enumerate(_JOINTS):
        c = stem + sfx
        if c not in q.columns:
            continue
        ang = q.column(c)
        axes[0, j].plot(x[sel], sign * np.rad2deg(ang[sel]), color="#1565c0", label="this session")
        axes[0, j].set_title(title)
        axes[0, j].set_ylabel("angle (deg)")
        if tq is not None and c in tq.columns:
            tau = tq.column(c)
            axes[1, j].plot(
                x[sel], sign * tau[sel] / mass, color="#c62828", label="net joint moment"
            )
            axes[1, j].set_ylabel("moment (N·m/kg)")
            power = tau * np.gradient(ang) / dt
            axes[2, j].plot(x[sel], power[sel] / mass, color="#2e7d32", label="joint power")
            axes[2, j].set_ylabel("power (W/kg)")
        for r in range(3):
            if axes[r, j].lines:
                axes[r, j].legend(fontsize=7, loc="best")
        axes[2, j].set_xlabel(xl)
    fig.tight_layout()
    return _svg(fig, laid_out=True)


def _fig_muscles(res: SessionResults) -> str | None:
    if not res.has("muscle_forces"):
        return None
    plt = _plt()
    sfx = _side(res)
    mf = res.table("muscle_forces")
    x, sel, xl = _cycle_axis(res, mf.time)
    idx = [k for k, c in enumerate(mf.columns) if c.endswith(sfx)]
    if not idx:
        return None
    peaks = np.nan_to_num(np.nanmax(np.abs(mf.data[:, idx]), axis=0, initial=0.0))
    top = [idx[k] for k in np.argsort(peaks)[::-1][:8]]
    fig, ax = plt.subplots(figsize=(7.5, 3.2))
    for k in top:
        ax.plot(x[sel], mf.data[sel, k], label=mf.columns[k])
    ax.set_xlabel(xl)
    ax.set_ylabel("muscle force (N)")
    ax.legend(fontsize=7, ncol=2, title="8 largest")
    return _svg(fig)


def _fig_contact(res: SessionResults) -> str | None:
    """Predicted knee contact force, total and (two-point model) medial and lateral, against
    the instrumented implant's measurement where there is one."""
    if not res.has("knee_contact"):
        return None
    plt = _plt()
    kc = res.table("knee_contact")
    x, sel, xl = _cycle_axis(res, kc.time)
    comps = [c for c in ("total", "medial", "lateral") if f"generic_{c}_bw" in kc.columns]
    fig, axes = plt.subplots(1, len(comps), figsize=(7.5, 2.8), sharey=True, squeeze=False)
    style = {
        "measured": ("k", "-", "measured (instrumented implant)"),
        "generic": ("#9e9e9e", "--", "predicted, generic parameters"),
        "subject_specific": ("#1565c0", "-", "predicted, subject-specific"),
    }
    # the like component: an axial measured total against the predicted axial force
    cmp = res.summary.comparison
    agree = cmp.knee_contact("generic") if cmp else None
    axial = bool(agree and agree.component == "axial total" and "generic_axial_bw" in kc.columns)
    for ax, comp in zip(axes[0], comps):
        for key, (c, ls, lab) in style.items():
            pred = "axial" if comp == "total" and axial and key != "measured" else comp
            col = f"{key}_{pred}_bw"
            if col in kc.columns:
                ax.plot(x[sel], kc.column(col)[sel], color=c, ls=ls, label=lab)
        ax.set_title("total (axial)" if comp == "total" and axial else comp, fontsize=9)
        ax.set_xlabel(xl)
    axes[0][0].set_ylabel("knee contact force (body weights)")
    axes[0][0].legend(fontsize=6)
    fig.tight_layout()
    return _svg(fig, laid_out=True)


def _fig_fes(res: SessionResults) -> str | None:
    """Measured vs simulated knee angle of the FES cross-validation trial ([2], Fig. 5b)."""
    if not res.has("fes_validation"):
        return None
    tb = res.table("fes_validation")
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 3.0))
    ax.plot(
        tb.time,
        np.rad2deg(tb.column("knee_angle_measured")),
        color="k",
        lw=1.2,
        label="measured (goniometer)",
    )
    ax.plot(
        tb.time,
        np.rad2deg(tb.column("knee_angle_simulated")),
        color="#1565c0",
        lw=1.2,
        label="simulated, identified model",
    )
    if "knee_angle_simulated_k_s0" in tb.columns:
        ax.plot(
            tb.time,
            np.rad2deg(tb.column("knee_angle_simulated_k_s0")),
            color="#ef6c00",
            lw=0.9,
            ls="--",
            label="simulated before k_s identification",
        )
    ax.invert_yaxis()
    ax.set_xlabel("time (s)")
    ax.set_ylabel("knee angle (deg, 0 = full extension)")
    ax.set_title(
        "Cross-validation trial (stimulation pattern not used for identification)", fontsize=9
    )
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3)
    return _svg(fig)


_FIGURES = (
    ("strength", _fig_strength),
    ("strength_curves", _fig_strength_curves),
    ("mass", _fig_mass),
    ("joints", _fig_joints),
    ("muscles", _fig_muscles),
    ("contact", _fig_contact),
    ("fes", _fig_fes),
)


def _draw(res: SessionResults, names: Sequence[str]) -> dict[str, str]:
    out = {}
    for name, fn in _FIGURES:
        if name not in names:
            continue
        try:
            svg = fn(res)
        except Exception as exc:  # a figure that cannot be drawn must not cost the report
            svg = (
                f'<p class="warn">This figure could not be drawn ({_e(type(exc).__name__)}: '
                f"{_e(' '.join(str(exc).split())[:200])}); the tables hold its numbers.</p>"
            )
        if svg:
            out[name] = svg
    return out


def build_figures(res: SessionResults) -> dict[str, str]:
    """Inline SVG figures by name (strength, strength_curves, mass, joints, muscles, contact,
    fes). Drawing them is most of a session's report (~0.05–0.25 s a figure with matplotlib);
    with a second CPU free (:func:`msk._runtime.fork.spare_cpu`) a forked child draws half of them
    meanwhile — the same figures, in about half the wall time."""
    from msk._runtime.fork import take_server

    server = take_server(FIGURE_SERVER)
    if server is not None:  # forked by `msk run` before its imports (msk._runtime.fork.Server)
        try:
            return dict(server.call(res))
        except RuntimeError:
            pass
    return _draw_all(res)


#: key of the :class:`msk._runtime.fork.Server` that draws the figures (``msk run`` starts it)
FIGURE_SERVER = "figures"


def _warm() -> None:
    """Load what the first figure of a process loads (fonts, text layout, the SVG backend)."""
    fig, ax = _plt().subplots(figsize=(2.0, 1.5))
    ax.plot([0.0, 1.0], [0.0, 1.0], label="warm-up")
    ax.set_xlabel("x (unit)")
    ax.legend()
    fig.tight_layout()
    _svg(fig)


def _draw_all(res: SessionResults) -> dict[str, str]:
    from msk._runtime.fork import Forked, spare_cpu

    names = [n for n, _ in _FIGURES]
    if not spare_cpu():
        return _draw(res, names)
    _plt()  # matplotlib imported once, before the fork
    # halves of about equal cost (joints, strength_curves and contact are the dear ones)
    theirs = ("strength_curves", "contact", "strength", "fes")
    child = Forked(_draw, res, theirs)
    both = {**_draw(res, [n for n in names if n not in theirs]), **child.result()}
    return {n: both[n] for n in names if n in both}


# ---------------------------------------------------------------------------------------------
# HTML
# ---------------------------------------------------------------------------------------------
_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Arial,sans-serif;margin:0;
 color:#222;background:#fafafa}
main{max-width:1100px;margin:0 auto;padding:16px 24px;background:#fff}
h1{font-size:1.6em;margin:.2em 0}h2{border-bottom:2px solid #1565c0;padding-bottom:2px;
 margin-top:1.6em;font-size:1.25em}h3{font-size:1.05em}
table{border-collapse:collapse;margin:8px 0;font-size:.88em;max-width:100%}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#eceff1}td:first-child,th:first-child{text-align:left}
table.strength td:nth-child(2),table.strength th:nth-child(2){text-align:left;white-space:normal}
.wrap{overflow-x:auto;max-width:100%}
.note{color:#555;font-size:.88em}.plain{background:#e3f2fd;padding:8px 12px;border-radius:4px}
.warn{background:#fff3e0;border-left:4px solid #ef6c00;padding:6px 10px;margin:6px 0}
.na{color:#b71c1c;font-weight:600}
svg{max-width:100%;height:auto}figure{margin:8px 0}
.flag{display:inline-block;width:10px;height:10px;border-radius:2px;margin-right:4px}
.status{white-space:nowrap}.ok{color:#2e7d32}.bad{color:#b71c1c;font-weight:600}
ol.refs{font-size:.85em;color:#333}
@page{size:A4;margin:12mm}
@media print{body{background:#fff}main{max-width:none;padding:0}
 h2{page-break-after:avoid}figure{page-break-inside:avoid}tr{page-break-inside:avoid}
 .wrap{overflow:visible}
 table{width:100%;font-size:.72em}
 th,td{white-space:normal;overflow-wrap:anywhere;padding:2px 3px}}
"""


#: Internal names of the literature in strings of a run (method names, messages) → citations.
_CITATIONS = {
    "seeds/000": "ref. [2]",
    "seeds/001": "a companion FES identification study",
    "seeds/002": "Hayashibe et al. [1]",
    "seeds/003": "ref. [3]",
    "seeds/004": "ref. [4]",
}


def _e(x: Any) -> str:
    """HTML-escaped text (a ``<script>`` or ``$`` from a data file is shown literally), with the
    literature cited instead of internal document names."""
    text = re.sub(r"seeds/00\d", lambda m: _CITATIONS.get(m.group(0), "the literature"), str(x))
    return html.escape(text)


def _finite(x: Any) -> TypeGuard[float]:
    return isinstance(x, (int, float)) and bool(np.isfinite(x))


def _kkt_table(kkt: Any) -> str:
    """The worst KKT figures of the tension QPs (``optimization.kkt``) and their gate."""
    tol = kkt.relative_tolerance
    rows = []
    for name in ("stationarity", "primal_feasibility", "dual_feasibility", "complementarity"):
        f = getattr(kkt, name)
        if f is None:
            continue
        rows.append(
            [
                _e(name.replace("_", " ")),
                _num(f.max, ".1e"),
                _num(f.relative_max, ".1e"),
                _e(_or(f.frame, "—")),
                _num(f.time_s, ".3f", "s"),
                _check(f.relative_max, tol) if tol is not None else "—",
            ]
        )
    note = (
        f'<p class="note">KKT check of the {_e(_or(kkt.frames, "—"))} frames the QP solver '
        "called optimal (infeasible frames excluded): the largest figure (scaled variables), "
        "the largest relative to its scale (the gradient's magnitude; the torques' for primal "
        f"feasibility) and its frame; gate ≤ {_num(tol, '.0e')}.</p>"
    )
    return note + _table(
        ["KKT figure", "max", "max relative", "frame", "time", "check"], rows, "kkt"
    )


def _status_html(word: str) -> str:
    """A status word with its colour swatch and its meaning as a tooltip."""
    col = STATUS_COLOURS.get(word, "#9e9e9e")
    return (
        f'<span class="status" title="{_e(STATUS_MEANING.get(word, ""))}">'
        f'<span class="flag" style="background:{col}"></span>{_e(word)}</span>'
    )


def _num(x: Any, fmt: str = ".3g", unit: str = "") -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "—"
    s = format(x, fmt)
    return f"{s} {unit}".rstrip() if unit else s


def _or(x: Any, default: Any) -> Any:
    """``x``, or ``default`` when the summary does not have it (``None``)."""
    return default if x is None else x


def _anthropometry_masses(s: Summary) -> dict[str, float | None]:
    """The anthropometric table's segment masses (kg) by segment name."""
    anth = s.anthropometry
    return {} if anth is None else {k: v.mass_kg for k, v in anth.segments.items()}


def _table(head: Sequence[str], rows: Sequence[Sequence[str]], cls: str = "") -> str:
    h = "".join(f"<th>{_e(c)}</th>" for c in head)
    b = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return (
        f'<div class="wrap"><table class="{cls}"><thead><tr>{h}</tr></thead>'
        f"<tbody>{b}</tbody></table></div>"
    )


def _na(res: SessionResults, *stages: str) -> str:
    for item in res.summary.not_available or ():
        if item.stage in stages:
            return (
                f'<p class="na">Not available: stage “{_e(item.stage)}” '
                f"{_e(item.status)} — {_e(item.reason)}</p>"
            )
    return ""


def _strength_section(res: SessionResults, figs: Mapping[str, str]) -> str:
    st = res.summary.strength
    out = ["<h2>1. Muscle strength</h2>"]
    if not st:
        return (
            "".join(out)
            + _na(res, "strength_identification", "emg")
            + ('<p class="na">Strength was not identified in this session.</p>')
        )
    side = _or(res.summary.subject.side, "right")
    other = "right" if side == "left" else "left"
    status = [st.group_status(g) for g in st.groups]
    ident = [g for g, w in zip(st.groups, status) if w == "identified"]
    weaker = [g.group for g in ident if _finite(g.ci_high) and g.ci_high < 1.0]
    stronger = [g.group for g in ident if _finite(g.ci_low) and g.ci_low > 1.0]
    counts = {w: status.count(w) for w in STATUS_COLOURS if status.count(w)}
    r2 = st.r2
    r2_min = _or(st.r2_min, STRENGTH_R2_MIN)
    unreliable = not _finite(r2) or r2 < r2_min
    bounds = st.bounds or ("—", "—")
    n = len(status)
    msg = (
        f"Strength of the {side} leg muscles measured with EMG, relative to a typical adult "
        f"(the generic model = 1.0). Of {n} muscle groups, "
        + ", ".join(f"{c} {w}" for w, c in counts.items())
        + ". "
    )
    if not ident:
        msg += (
            "No group's strength is determined by this session's data: the values below must "
            "not be read as the subject's strength. "
        )
    else:
        msg += (
            f"Clearly below typical: {', '.join(weaker)}. "
            if weaker
            else "No identified group is clearly below typical. "
        )
        msg += f"Clearly above typical: {', '.join(stronger)}. " if stronger else ""
    msg += (
        f"The {other} leg was not measured with EMG, so no left/right comparison of strength "
        "is possible in this session."
    )
    out.append(f'<p class="plain">{_e(msg)}</p>')
    if unreliable:
        out.append(
            f'<p class="warn"><b>Caution:</b> the EMG-driven muscle model explains the '
            f"joint moments poorly over all rows: fit r² = {_num(r2, '.2f')}, below "
            f"{_num(r2_min, '.2f')}. Each group is judged on the fit of its own joints' rows "
            f"(below); factors at the bounds ({_e(bounds[0])} or {_e(bounds[1])} ×) were "
            "fixed by the bound, not by the data, and are never identified.</p>"
        )
    no_mvc = any("no MVC" in w for w in res.summary.quality.emg_warnings or ())
    if no_mvc:
        out.append(
            '<p class="warn">No maximal voluntary contraction (MVC) trials: EMG is '
            "normalised to this session's peak, so activations are relative and the "
            "strength factors are biased: a muscle whose EMG is divided by a sub-maximal peak "
            "reaches activations near 1, its EMG-driven force is too large for the joint "
            "moments, and its factor is pinned low — it looks weak (often at the lower "
            "bound).</p>"
        )
    pct = round(100 * _or(st.confidence, 0.95))
    rows = []
    for g, word in zip(st.groups, status):
        ci = (
            f"{_num(g.ci_low, '.2f')}–{_num(g.ci_high, '.2f')} ×"
            if word != "prior" and _finite(g.ci_low) and _finite(g.ci_high)
            else "—"
        )
        rows.append(
            [
                _e(g.group),
                _e(", ".join(g.muscles)),
                # a "prior" group's factor is the generic one the data did not change
                "generic (kept)" if word == "prior" else _num(g.factor, ".2f", "×"),
                ci,
                _num(g.f_iso_generic_n, ".0f", "N"),
                # an F_iso is a finding only for an identified group
                _num(g.f_iso_n, ".0f", "N") if word == "identified" else "—",
                _status_html(word),
            ]
        )
    out.append(
        _table(
            [
                "group (EMG)",
                f"muscles ({side})",
                "strength factor",
                f"{pct} % CI (bootstrap)",
                "generic F_iso",
                "estimated F_iso",
                "status",
            ],
            rows,
            "strength",
        )
    )
    out.append(_status_legend())
    failed = tuple(st.failed_channels or ())
    out.append(
        _strength_next_tests((*st.groups, *failed), (*status, *("not determined",) * len(failed)))
    )
    lo, hi = LITERATURE_FACTOR_RANGE
    out.append(
        f'<p class="note">Literature range of strength factors: {lo}–{hi} × generic '
        f"(thesis [3], Table 3.1); generic F_iso: gait2392 (Delp et al. 1990 [6]). "
        f"{other.capitalize()} side: not measured (no EMG).</p>"
    )
    out.append(
        f'<p class="note">Fit r² of all rows = {_num(r2, ".3f")} (dimensionless; a group '
        f"needs r² ≥ {_num(r2_min, '.2f')} on its own joints' rows); method: {_e(st.method)}; "
        "factors "
        f"bounded to {_e(bounds[0])}–{_e(bounds[1])} × generic (Hayashibe et al. "
        "[1], §V; thesis [3], Table 3.1). A group is “identified” only when its factor and its "
        "whole interval lie strictly inside the bounds and the fit of its own rows reaches the "
        "threshold.</p>"
    )
    if "strength" in figs:
        out.append(f"<figure>{figs['strength']}</figure>")
    out.append(_joint_strength_html(st, figs))
    return "".join(out)


def _strength_next_tests(groups: Sequence[Any], status: Sequence[str]) -> str:
    """Each group not identified: its reason and the test that would identify it (the
    summary's ``strength.groups[*].reason`` and ``.protocol``)."""
    items = []
    for g, word in zip(groups, status):
        if word == "identified":
            continue
        reason = getattr(g, "reason", None) or word
        proto = getattr(g, "protocol", None)
        text = proto.get("text") if proto else None
        nxt = (
            f" <b>Next protocol:</b> {_e(text)}."
            if text
            else " No isometric test of the model's joint actions loads this group."
        )
        items.append(f"<li><b>{_e(g.group)}</b> ({_e(word)}): {_e(reason)}.{nxt}</li>")
    if not items:
        return ""
    return (
        "<h3>Groups not identified: why, and the test that would identify them</h3>"
        '<p class="note">Tests computed from the subject\'s model: the isometric maximal '
        "contraction where the group's moment arm × force–length is largest and its "
        "synergists' share smallest; record it with the group's EMG.</p>"
        "<ul>" + "".join(items) + "</ul>"
    )


def _joint_strength_html(st: Strength, figs: Mapping[str, str]) -> str:
    """Sub-section "joint strength": peak maximal isometric moments per action, generic vs
    identified, with the status of the identified curve (summary ``strength.joint_strength``)."""
    js = st.joint_strength
    if not js:
        return ""
    out = ["<h3>Joint strength (maximal isometric moments)</h3>"]
    if js.error:
        return out[0] + f'<p class="na">Not available: {_e(js.error)}</p>'
    mass = js.mass_kg
    per_kg = _finite(mass) and mass > 0
    acts = js.actions or ()
    undetermined = [a.action for a in acts if a.status in ("at bound", "not determined")]
    msg = (
        "Largest moment each muscle group of the model can produce at full effort, without "
        "movement, over the joint's range: the generic model (a typical adult scaled to the "
        "subject) beside the model with this session's identified strength."
    )
    if undetermined:
        msg += (
            " For " + ", ".join(undetermined) + " the identified curve is not determined (its "
            "muscle groups are at a bound or not determined): it must not be read as the "
            "subject's strength, and only the generic curve is shown."
        )
    out.append(f'<p class="plain">{_e(msg)}</p>')
    rows = []
    for a in acts:
        word = _or(a.status, "prior")
        gp, ip = a.generic_peak_nm, a.identified_peak_nm
        gen = f"{_num(gp, '.0f', 'N·m')}"
        if per_kg and mass:
            gen += f" ({_num(gp / mass, '.2f', 'N·m/kg')})" if _finite(gp) else ""
        gen += f" at {_num(a.generic_peak_angle_deg, '.0f', '°')}"
        if word in ("at bound", "not determined"):
            ide = "not determined"
        elif word == "prior":
            ide = "= generic (no identified group carries this action)"
        else:
            ide = f"{_num(ip, '.0f', 'N·m')}"
            if per_kg and mass and _finite(ip):
                ide += f" ({_num(ip / mass, '.2f', 'N·m/kg')})"
            ide += f" at {_num(a.identified_peak_angle_deg, '.0f', '°')}"
        groups = ", ".join(
            f"{g.group} {100 * _or(g.share, np.nan):.0f} % ({g.status})" for g in a.groups or ()
        )
        posture = ", ".join(f"{k} {v:.0f}°" for k, v in (a.posture_deg or {}).items())
        rows.append(
            [
                _e(a.action),
                _e(f"{a.angle_label} {a.angles_deg[0]:.0f}–{a.angles_deg[-1]:.0f}°"
                   + (f"; {posture}" if posture else "")),
                gen,
                _e(ide),
                _e(groups or "none (generic muscles only)"),
                _status_html(word),
            ]
        )  # fmt: skip
    side = _or(js.side, "")
    out.append(
        _table(
            [
                "action",
                "angle range; posture held",
                "generic peak (at angle)",
                "identified peak (at angle)",
                "groups (share of peak, status)",
                "status",
            ],
            rows,
            "strength joint-strength",
        )
    )
    if "strength_curves" in figs:
        out.append(f"<figure>{figs['strength_curves']}</figure>")
    share = _or(js.status_share_min, 0.05)
    out.append(
        f'<p class="note">{_e(side.capitalize())} side; every agonist (moment arm in the '
        "direction of the action) at full activation, rigid tendon, zero velocity, active fibre "
        "force only; antagonists silent. Coordinates not swept at 0° except the posture listed "
        "(knee flexion is knee_angle < 0 in the model). Status of an identified curve: not "
        f"determined when a group carrying ≥ {100 * share:.0f} % of the peak is at a bound or "
        "not determined; identified when such a group is identified; otherwise the generic "
        f"curve. N·m/kg: body mass {_num(mass, '.1f', 'kg')}. {_e(_or(js.norms_note, ''))}"
        "</p>"
    )
    return "".join(out)


def _status_legend() -> str:
    return (
        '<p class="note">Status: '
        + "; ".join(f"{_status_html(w)} — {_e(m)}" for w, m in STATUS_MEANING.items())
        + ".</p>"
    )


#: Words for the identification's segment and parameter names (weak directions in words).
_SEGMENT_WORDS = {
    "pelvis": "pelvis",
    "torso": "torso (trunk, head and arms)",
    "femur": "thigh",
    "tibia": "shank",
    "talus": "ankle bone (talus)",
    "calcn": "foot (heel)",
    "toes": "toes",
}
_PARAMETER_WORDS = {
    "m": "mass",
    "mx": "mass-centre position (front–back)",
    "my": "mass-centre position (along the segment)",
    "mz": "mass-centre position (sideways)",
}


def _segment_words(name: str) -> str:
    both = "(+_l)" in name
    base = name.replace("(+_l)", "")
    stem, side = (base[:-2], base[-2:]) if base[-2:] in ("_r", "_l") else (base, "")
    word = _SEGMENT_WORDS.get(stem, stem)
    if both:
        plural = {"thigh": "thighs", "shank": "shanks", "foot (heel)": "feet (heel)"}.get(
            word, word.replace("ankle bone", "ankle bones")
        )
        return f"{plural} (left and right together)"
    return {"_r": f"right {word}", "_l": f"left {word}"}.get(side, word)


def weak_direction_words(text: str) -> str | None:
    """A weak direction of the mass identification (``msk.dynamics.identification`` advice line
    ``weak direction (…): -0.59·pelvis.my +0.31·torso.m …``) in words, or None when ``text``
    is not one."""
    m = re.match(r"weak direction \((.*?)\):\s*(.*)$", text.strip())
    if not m:
        return None
    how, comb = m.groups()
    terms = re.findall(r"([+-]\d*\.?\d+)·(\S+)\.(\w+)", comb)
    if not terms:
        return None
    phrases: dict[str, set[int]] = {}
    for coef, seg, par in terms:
        what = _PARAMETER_WORDS.get(par, "rotational inertia")
        phrases.setdefault(f"the {_segment_words(seg)} {what}", set()).add(
            1 if float(coef) > 0 else -1
        )
    names = list(phrases)
    signs = set().union(*phrases.values())
    listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    if how.startswith("no data"):
        why = "this motion carries no information on this combination"
    else:
        r = re.search(r"([\d.]+(?:e[+-]?\d+)?)×", how)
        why = (
            f"the data are {r.group(1)} times less precise on this combination than the "
            "generic value's spread"
            if r
            else "the data barely inform this combination"
        )
    if len(names) == 1:
        return f"{listed[0].upper()}{listed[1:]} is not determined ({why})."
    if len(signs) > 1:
        return (
            f"The data cannot tell {listed} apart: only a weighted sum of them is determined, "
            f"not each one — shifting from one to the other fits the measurements equally well "
            f"({why})."
        )
    return (
        f"The data cannot tell the common level of {listed}: only their balance is determined "
        f"— raising or lowering them all together fits the measurements equally well ({why})."
    )


def _mass_section(res: SessionResults, figs: Mapping[str, str]) -> str:
    ident = res.summary.identification
    out = ["<h2>2. Mass distribution</h2>"]
    if not ident:
        return "".join(out) + _na(res, "mass_identification")
    anth = _anthropometry_masses(res.summary)
    status = [s.status_word() for s in ident.segments]
    counts = {w: status.count(w) for w in STATUS_COLOURS if status.count(w)}
    out.append(
        '<p class="plain">Body segment masses estimated from this session\'s motion and '
        f"ground forces. Of {len(status)} segments, "
        + _e(", ".join(f"{c} {w}" for w, c in counts.items()))
        + ". Only “identified” segments are determined by the data; “prior” segments keep the "
        "generic value; “not determined” segments moved from the generic value without the "
        "data pinning them down — read their masses as uncertain.</p>"
    )
    rows = []
    for s, word in zip(ident.segments, status):
        n = s.name
        key = ("foot" + n[-2:]) if n.startswith("calcn") else n
        tab = anth.get(key)
        com = s.com_m or (None,) * 3
        prior = s.prior_mass_kg
        change = (
            100.0 * (s.mass_kg - prior) / prior  # type: ignore[operator]
            if _finite(prior) and prior > 0
            else None
        )
        rows.append(
            [
                _e(n),
                _num(s.mass_kg, ".2f", "kg"),
                _num(s.mass_std_kg, ".2f", "kg"),
                _num(prior, ".2f", "kg"),
                _num(change, "+.0f", "%"),
                _num(tab, ".2f", "kg") if tab is not None else "—",
                " ".join(_num(c, "+.3f") for c in com) + " m",
                _status_html(word),
            ]
        )
    out.append(
        _table(
            [
                "segment",
                "estimated mass",
                "± SD",
                "scaled generic",
                "change",
                "anthropometric table",
                "COM (x y z, body frame)",
                "status",
            ],
            rows,
            "mass",
        )
    )
    out.append(_status_legend())
    out.append(
        f'<p class="note">Condition number of the base regressor '
        f"{_num(ident.condition_number, '.3g')} (dimensionless), "
        f"{_e(ident.n_frames)} frames. Base-link equations after Hayashibe et al. [1], §II. "
        "“Identified”: posterior SD of the mass ≤ 2 % and of every COM coordinate ≤ 4 mm; "
        "“prior”: mass and COM within 0.2 prior SD (6 %, 6 mm) of the generic value. Table "
        "masses: Dumas et al. 2007 [7] (foot row on the calcaneus; talus and toes are part of "
        "it; torso = trunk + head + arms).</p>"
    )
    at_prior = [s.name for s, w in zip(ident.segments, status) if w == "prior"]
    advice = list(ident.advice or ())
    if any(a.startswith("not excited") for a in advice) and at_prior:
        out.append(
            '<p class="warn">Not excited by this motion (kept at the generic value): '
            f"{_e(', '.join(at_prior))}. Move these segments more (larger, faster, "
            "multi-planar motion) to identify them.</p>"
        )
    seen: list[str] = []
    for a in advice:
        words = weak_direction_words(a)
        if words and words not in seen:
            seen.append(words)
    if seen:
        out.append(
            '<div class="warn">Parameter combinations this motion does not determine:<ul>'
            + "".join(f"<li>{_e(w)}</li>" for w in seen[:5])
            + "</ul></div>"
        )
    for a in advice:
        if not a.startswith(("not excited", "weak direction")):
            out.append(f'<p class="warn">{_e(a)}</p>')
    if "mass" in figs:
        out.append(f"<figure>{figs['mass']}</figure>")
    return "".join(out)


def _gait_section(res: SessionResults, figs: Mapping[str, str]) -> str:
    cyc = res.summary.gait_cycle_s
    over = "the gait cycle" if cyc else "the trial"
    out = [f"<h2>3. Joint angles, moments, powers and muscle forces over {over}</h2>"]
    side = _or(res.summary.subject.side, "right")
    if cyc:
        out.append(
            f'<p class="note">Gait cycle of the {_e(side)} leg from foot strike '
            f"{cyc[0]:.3f} s to foot strike {cyc[1]:.3f} s (C3D events), shown as 0–100 %."
            " Moments are internal net joint moments per kg body mass; positive = flexion"
            " (hip, knee) or dorsiflexion (ankle) for angles and moments alike. Power = moment"
            " × angular velocity (W/kg; positive = generation).</p>"
        )
    else:
        out.append(
            '<p class="note">No gait cycle: no two foot strikes of the side of interest (a '
            "task without steps — standing, a squat — or events missing): curves are shown "
            "against time. Moments: internal net joint moments per kg body mass; frames in which "
            "a foot stands on a surface no plate measures are left blank for that leg.</p>"
        )
    if "joints" in figs:
        out.append(f"<figure>{figs['joints']}</figure>")
    if "muscles" in figs:
        out.append(f"<h3>Muscle forces ({_e(side)} leg)</h3><figure>{figs['muscles']}</figure>")
    else:
        out.append(_na(res, "tension_optimization", "muscle_geometry"))
    return "".join(out)


def _contact_section(res: SessionResults, figs: Mapping[str, str]) -> str:
    out = ["<h2>4. Knee contact force</h2>"]
    if "contact" not in figs:
        return "".join(out) + _na(res, "knee_contact", "tension_optimization")
    comp = res.summary.comparison
    rows = []
    for (v, vl), (part, pl) in (
        (variant, part)
        for variant in (("generic", "generic parameters"), ("subject_specific", "subject-specific"))
        for part in (("total", ", total"), ("medial", ", medial"), ("lateral", ", lateral"))
    ):
        c = comp.knee_contact(v, part) if comp else None
        if c:
            rows.append(
                [
                    _e(f"{vl}, {c.component}" if c.component else f"{vl}{pl}"),
                    _num(c.peak_predicted_bw, ".2f", "BW"),
                    _num(c.peak_measured_bw, ".2f", "BW"),
                    _num(c.rms_bw, ".2f", "BW"),
                    _num(c.rms_n, ".0f", "N"),
                    _num(c.nrmsd_pct, ".1f", "%"),
                    _num(c.pearson_r, ".2f"),
                    _num(c.icc, ".2f"),
                ]
            )
    if rows:
        out.append(
            '<p class="plain">Force between femur and tibia in body weights (BW), '
            "predicted from the muscle forces and compared with the force measured by "
            "the instrumented knee implant.</p>"
        )
        out.append(
            _table(
                [
                    "prediction",
                    "peak predicted",
                    "peak measured",
                    "RMS error",
                    "RMS error",
                    "NRMSD",
                    "Pearson r (dimensionless)",
                    "ICC (dimensionless)",
                ],
                rows,
                "contact",
            )
        )
    else:
        out.append(
            '<p class="note">No measured contact force for this session: prediction only.</p>'
        )
    out.append(f"<figure>{figs['contact']}</figure>")
    return "".join(out)


#: Quality-gate quantities shown as rows of the data-quality table.
_QUALITY_ROW_QUANTITIES = {
    "ik_marker_rms_mean_m",
    "ik_marker_max_mean_m",
    "residual_force_rms_pct_bw",
    "residual_moment_rms_pct_com_height_peak_force",
    "plate_mass_difference_pct",
    "optimization_infeasible_frames",
}


def _check(
    value: Any,
    limit: float,
    *,
    flagged: bool | None = None,
    below: bool = True,
    needs_value: bool = True,
) -> str:
    """'ok' / 'over threshold' (or 'below threshold') for a quality figure. ``flagged`` (whether
    the gate of ``summary.quality.flags`` was raised) decides when the run checked it (not
    None); otherwise the value is compared with ``limit``."""
    if needs_value and value is None and not flagged:
        return '<span class="note">not checked</span>'
    if flagged is not None:
        bad = flagged
    elif not _finite(value):
        return '<span class="note">not checked</span>'
    else:
        bad = value > limit if below else value < limit
    if not bad:
        return '<span class="ok">✓ ok</span>'
    word = "over threshold" if below else "below threshold"
    return f'<span class="bad">⚠ {word}</span>'


def _quality_section(res: SessionResults) -> str:
    from msk.quality import THRESHOLDS as TH

    s = res.summary
    q = s.quality
    flags = q.flags or ()
    raised = {f.quantity for f in flags}

    def gate(quantity: str) -> bool | None:
        return (quantity in raised) if q.flags is not None else None

    plate = [f for f in flags if f.quantity == "plate_mass_difference_pct"]
    out = ["<h2>5. Data quality</h2>"]
    ik_mean = q.ik_marker_rms_mean_m
    ik_max = q.ik_marker_rms_max_m
    rf = q.residual_force_rms_pct_bw
    flat = q.emg_flat_channels or ()
    st = s.strength
    r2_min = _or(st.r2_min, STRENGTH_R2_MIN) if st else STRENGTH_R2_MIN
    n_frames = q.frames
    rows = [
        [
            "frames",
            f"{_e(n_frames if n_frames is not None else '—')} at {_num(q.rate_hz, '.0f', 'Hz')}",
            "—",
            "—",
        ],
        [
            "IK marker error, mean",
            _num(1000 * ik_mean, ".1f", "mm") if _finite(ik_mean) else "—",
            f"≤ {1000 * TH['ik_marker_rms_mean_m']:g} mm [5]",
            _check(ik_mean, TH["ik_marker_rms_mean_m"], flagged=gate("ik_marker_rms_mean_m")),
        ],
        [
            "IK marker error, worst frame",
            _num(1000 * ik_max, ".1f", "mm") if _finite(ik_max) else "—",
            f"worst marker ≤ {1000 * TH['ik_marker_max_mean_m']:g} mm on average [5]",
            _check(ik_max, TH["ik_marker_max_mean_m"], flagged=gate("ik_marker_max_mean_m")),
        ],
        ["marker most often worst", _e(_or(q.ik_worst_marker, "—")), "—", "—"],
        [
            "IK failed frames",
            _e(_or(q.ik_failed_frames, "—")),
            "0",
            _check(q.ik_failed_frames, 0),
        ],
        [
            "frames with all ground contact on plates (residuals, muscle forces)",
            f"{_e(_or(q.contact_measured_frames, '—'))} of {_e(_or(q.frames, '—'))}",
            "—",
            "—",
        ],
        [
            "of those, frames whose leg segments the markers observe (residuals, identification)",
            f"{_e(_or(q.observed_measured_frames, '—'))}",
            f"≥ {TH['observed_measured_frames_min_pct']:g} %",
            "—",
        ],
        [
            "frames with a foot on an unmeasured surface (that leg's torques not written)",
            f"{_e(_or(q.unmeasured_contact_frames, '—'))} "
            f"({_num(q.unmeasured_contact_inside_pct, '.0f', '%')} of the measured span)",
            f"≤ {TH['unmeasured_contact_inside_pct']:g} % of the span",
            _check(
                q.unmeasured_contact_inside_pct,
                TH["unmeasured_contact_inside_pct"],
                flagged=gate("unmeasured_contact_inside_pct"),
            ),
        ],
        [
            "pelvis residual force (RMS)",
            f"{_num(q.residual_force_rms_n, '.1f', 'N')} ({_num(rf, '.1f', '% BW')})",
            f"≤ {TH['residual_force_rms_pct_bw']:g} % BW [5]",
            _check(rf, TH["residual_force_rms_pct_bw"], flagged=gate("residual_force_rms_pct_bw")),
        ],
        [
            "pelvis residual moment (RMS)",
            _num(q.residual_moment_rms_nm, ".1f", "N·m"),
            f"≤ {TH['residual_moment_rms_pct_com_height_peak_force']:g} % of COM height × peak "
            "external force [5]",
            _check(
                q.residual_moment_rms_nm,
                np.inf,
                flagged=gate("residual_moment_rms_pct_com_height_peak_force"),
            ),
        ],
        [
            "body mass weighed by the force plates vs configured",
            _num(plate[0].value, "+.1f", "%") if plate else "—",
            f"within ±{TH['body_mass_difference_pct']:g} %",
            _check(None, 0.0, flagged=gate("plate_mass_difference_pct"), needs_value=False),
        ],
        [
            "EMG channels flat / unusable",
            _e(", ".join(flat) or "none"),
            "none",
            _check(len(flat), 0) if q.emg_flat_channels is not None else "—",
        ],
        [
            "optimisation infeasible frames",
            _e(_or(q.optimization_infeasible_frames, "—")),
            "0",
            _check(
                q.optimization_infeasible_frames,
                0,
                flagged=gate("optimization_infeasible_frames"),
            ),
        ],
    ]
    if st:
        rows.append(
            [
                "strength fit r² (EMG-driven model vs joint moments)",
                _num(st.r2, ".2f"),
                f"≥ {_num(r2_min, '.2f')} for any group to be identified",
                _check(st.r2, r2_min, below=False),
            ]
        )
    other = [f for f in flags if f.quantity not in _QUALITY_ROW_QUANTITIES]
    out.append(_table(["figure", "value", "threshold", "check"], rows, "quality"))
    if other:
        out.append(
            '<p class="note">Other gates raised (see the banner at the top): '
            + "; ".join(_e(f.message) for f in other)
            + ".</p>"
        )
    out.append(
        '<p class="note">Thresholds: IK and residuals after Hicks et al. 2015 [5] (stated '
        "there on peak values; applied here to the RMS over the frames the plates measure); "
        "the strength fit threshold is msk's (below it the EMG-driven model explains less than "
        "half of the joint-moment variance).</p>"
    )
    gaps = q.marker_gaps or ()
    if gaps:
        out.append(
            _table(
                ["marker with gaps", "missing frames", "longest gap (frames)"],
                [[_e(g.marker), _e(g.missing_frames), _e(g.longest_gap_frames)] for g in gaps],
                "gaps",
            )
        )
    warns = q.emg_warnings or ()

    no_mvc = [w.split("'")[1] for w in warns if "no MVC" in w and w.count("'") >= 2]
    for w in [w for w in warns if "no MVC" not in w][:8]:
        out.append(f'<p class="warn">EMG: {_e(w)}</p>')
    if no_mvc:
        out.append(
            f'<p class="warn">EMG: no MVC trial for {len(no_mvc)} channels '
            f"({_e(', '.join(no_mvc))}): each is normalised to its peak envelope in this "
            "session, so activations are relative, not % MVC.</p>"
        )
    return "".join(out)


#: Meaning of the FES model parameters (FES identification study [2], Eq. 1–7, 10).
_FES_MEANING = {
    "geometry.L_ext": "quadriceps muscle–tendon length at full extension",
    "geometry.r_q": "quadriceps moment arm",
    "knee.J": "shank + foot inertia about the knee",
    "knee.B": "knee viscous damping",
    "knee.K": "static torque (gravity + passive elasticity)",
    "muscle.F_cm": "maximal contractile force",
    "muscle.K_cm": "maximal contractile stiffness",
    "muscle.L_c0": "optimal contractile-element length",
    "muscle.b": "force–length width",
    "muscle.k_s": "series-element (tendon) stiffness",
    "muscle.L_s": "series-element slack length",
    "recruitment.c1": "recruitment sigmoid: maximum",
    "recruitment.c2": "recruitment sigmoid: slope",
    "recruitment.c3": "recruitment sigmoid: threshold (PW/PW_max)",
}
#: The protocol step whose fit identifies each FES parameter (the others are protocol priors).
_FES_PARAMETER_STEP = {
    "knee.K": "static_torque",
    "knee.J": "joint_mechanics",
    "knee.B": "joint_mechanics",
    "muscle.L_c0": "force_length",
    "muscle.b": "force_length",
    "muscle.F_cm": "recruitment",
    "recruitment.c1": "recruitment",
    "recruitment.c2": "recruitment",
    "recruitment.c3": "recruitment",
    "muscle.k_s": "nlp_ks",
}
_FES_STEPS = {
    "static_torque": "static torque (K)",
    "joint_mechanics": "joint mechanics, pendulum (J, B)",
    "force_length": "force–length (L_c0, b)",
    "recruitment": "recruitment (c1, c2, c3)",
    "nlp_ks": "NLP identification (k_s)",
    "cross_validation_initial": "cross-validation before k_s identification",
    "cross_validation": "cross-validation, identified model",
}


def _fes_references() -> tuple[dict[str, tuple[float, float]], dict[str, tuple[float, float]]]:
    """Parameter ranges (Table 3) and NRMSD ranges (Table 2) of the FES identification study
    [2] (literature, for context)."""
    from msk.fes.model import TABLE2_NRMSD_PCT, TABLE3

    t3 = {}
    for key in _FES_MEANING:
        grp, name = key.split(".")
        vals = [float(getattr(getattr(subj, grp), name)) for subj in TABLE3.values()]
        t3[key] = (min(vals), max(vals))
    t2 = {}
    for key, row in TABLE2_NRMSD_PCT.items():
        vals = [v for v in row if v is not None]
        t2[key] = (float(min(vals)), float(max(vals)))
    return t3, t2


def _fes_section(res: SessionResults, figs: Mapping[str, str], number: int) -> str:
    fes = res.summary.fes
    out = [f"<h2>{number}. FES knee model</h2>"]
    if not fes:
        return (
            "".join(out) + _na(res, "fes") + '<p class="na">The FES model was not identified.</p>'
        )
    t3, t2 = _fes_references()
    steps = _or(fes.steps, {})
    cv_step = steps.get("cross_validation")
    cv = cv_step.nrmsd_pct if cv_step else None
    from msk.fes.model import TABLE2_NRMSD_PCT

    seed_cv = [v for v in TABLE2_NRMSD_PCT["cross_validation"] if v is not None]
    out.append(
        '<p class="plain">A model of the knee moved by electrical stimulation of the quadriceps '
        "was fitted to this session's recordings. On a stimulation pattern it was not fitted "
        f"to, it predicts the knee angle with an error of {_num(cv, '.1f', '%')} of the "
        f"movement range (lower is better; the FES identification study [2] reported a "
        "median of "
        f"{float(np.median(seed_cv)):.1f} % in {len(seed_cv)} legs of spinal cord-injured "
        "subjects).</p>"
    )
    rows = []
    initial = fes.initial_parameters or {}
    for key, item in fes.parameters.items():
        unit = _or(item.unit, "")
        r = t3.get(key)
        step = _FES_PARAMETER_STEP.get(key)
        fit = steps.get(step) if step else None
        word = fes_status(
            item.value,
            prior=initial.get(key),
            from_prior=step is None,
            nrmsd_pct=fit.nrmsd_pct if fit else None,
            determined=key in FES_DETERMINED_BY_PROTOCOL,
        ).value
        rows.append(
            [
                _e(key),
                _e(_FES_MEANING.get(key, "")),
                _num(item.value, ".4g"),
                _e({"1": "dimensionless", "1 (PW/PW_max)": "PW/PW_max"}.get(unit, unit)),
                "—" if r is None else f"{r[0]:.4g} – {r[1]:.4g}",
                _status_html(word),
            ]
        )
    out.append("<h3>Model parameters</h3>")
    out.append(
        _table(
            ["parameter", "meaning", "value", "unit", "published range [2]", "status"],
            rows,
            "strength fes-parameters",
        )
    )
    out.append(_status_legend())
    out.append(
        '<p class="note">Model of the FES identification study [2] (Eq. 1–7, 10); the '
        "geometry (from the height), K_cm/F_cm and L_c0/(L_c0 + L_s) are priors of the protocol "
        "(session configuration [fes]). A parameter is “identified” when the NRMSD of the "
        f"protocol step that fits it is ≤ {FES_NRMSD_MAX_PCT:g} % of the movement range. "
        "Published ranges are the 13 legs of [2], Table 3 (L_s derived from an assumed optimal "
        "angle of 60°).</p>"
    )
    rows = []
    for key, label in _FES_STEPS.items():
        if key not in steps:
            continue
        r = t2.get(key)
        rows.append(
            [
                _e(label),
                _num(steps[key].nrmsd_pct, ".2f", "%"),
                _num(steps[key].nrmse_pct, ".2f", "%"),
                "—" if r is None else f"{r[0]:.2f} – {r[1]:.2f} %",
            ]
        )
    out.append("<h3>Fit per protocol step</h3>")
    out.append(
        _table(
            ["protocol step (parameters)", "NRMSD", "NRMSE", "published NRMSD range [2]"],
            rows,
            "fes-steps",
        )
    )
    out.append(
        '<p class="note">NRMSD = RMS(measured − simulated) / range(measured) × 100 '
        f"([2], Eq. 9); threshold for the step's parameters to be identified: ≤ "
        f"{FES_NRMSD_MAX_PCT:g} %.</p>"
    )
    if "fes" in figs:
        out.append(f"<figure>{figs['fes']}</figure>")
    return "".join(out)


def _scaling_note(model: Any) -> str:
    """How each leg segment was scaled (``summary.json`` ``model.scaling`` and
    ``model.leg_split``), escaped HTML; "" without a scaling record."""
    bodies = dict(((model.scaling or {}).get("bodies") or {}) if model is not None else {})
    if not bodies:
        return ""
    legs = [b for b in bodies if b.split("_")[0] in ("pelvis", "femur", "tibia", "calcn")]
    parts = [f"{b} × {float(bodies[b]['factors'][0]):.3f} ({bodies[b]['method']})" for b in legs]
    text = "Scaling of the leg segments: " + "; ".join(parts) + "."
    split = dict(model.leg_split or {})
    for side, sp in sorted(split.items()):
        how = str(sp.get("method"))
        why = str(sp.get("reason") or "")
        text += (
            f" Femur : tibia split, {'right' if side == 'r' else 'left'} leg (no knee or ankle "
            f"marker; one pelvis-to-heel factor {float(sp.get('leg_factor', 1.0)):.3f}): {how}"
            + (f" — {why}" if why else "")
            + "."
        )
    return _e(text)


def _placement_note(model: Any) -> str:
    """Which leg coordinates' means a placement from the motion leaves undetermined
    (``summary.json`` ``model.placement_determinacy``), escaped HTML; "" without one."""
    det = dict((model.placement_determinacy or {}) if model is not None else {})
    coords = dict(det.get("coordinates") or {})
    if not coords:
        return ""
    tol_mm = 1000 * float(det.get("tolerance_m", 0.0))

    def part(name: str, c: Mapping[str, Any]) -> str:
        dm = [float(v) for v in c.get("mean_change_deg", ())]
        dc = [1000 * float(v) for v in c.get("cost_change_m", ())]
        shifts = ", ".join(f"{m:+.1f}° → {d:+.3f} mm" for m, d in zip(dm, dc))
        verdict = c.get("prior") or c.get("status")  # "set by prior: …" when a prior sets it
        return f"{name} {float(c.get('mean_deg', 0.0)):.1f}° ({shifts}): {verdict}"

    text = (
        "Marker placement from the task (no static trial): each leg coordinate's mean shifted "
        f"by ±{float(det.get('shift_deg', 0.0)):g}° with the markers distal to its joint kept "
        "in place, the task's frames refitted (change of the mean → change of the task IK "
        f"cost; within {tol_mm:.1f} mm or below: not determined by the markers): "
        + "; ".join(part(n, c) for n, c in coords.items())
        + "."
    )
    return _e(text)


def _methods_section(res: SessionResults, number: int = 6, *, gait: bool = True) -> str:
    s = res.summary
    out = [f"<h2>{number}. Methods, stages and software</h2>"]
    if s.fes:
        out.append(
            '<p class="note">FES knee model ([2], §2.3): geometry from the height → '
            "static torque K → pendulum J, B → force–length L_c0, b → recruitment c1–c3, "
            "F_cm → series stiffness k_s by the NLP of Eq. 8 on the dynamic trial (repeated to "
            "a fixed point of k_s) → cross-validation on a trial not used for identification."
            "</p>"
        )
    if gait:
        plate_assignment = s.methods.plate_assignment if s.methods else None
        out.append(
            '<p class="note">Markers → scaled model (OpenSim-style measurements; non-model '
            "markers placed from the static trial) → inverse kinematics → force plates assigned "
            "to the feet → "
            "segment inertial parameters from the base-link equations ([1], §II) → inverse "
            "dynamics → EMG envelopes and activation ([1], Eq. 8) → muscle–tendon geometry "
            "([1], Eq. 6–7) → tension optimisation → strength by regression on the net "
            "contribution matrix ([1], Eq. 12–16) → tibiofemoral contact force from the tibia "
            "free-body diagram with the muscle forces ([4], §2.1), muscle paths evaluated at "
            "every frame. The lab frame is rotated into the model frame (vertical up, walking "
            f"along +x); force-plate contacts: {_e(_or(plate_assignment, '?'))}."
            "</p>"
        )
        filtering = s.methods.filtering if s.methods else None
        if filtering:
            out.append(f'<p class="note">Filtering: {_e(filtering)}.</p>')
        scaling_note = _scaling_note(s.model)
        if scaling_note:
            out.append(f'<p class="note">{scaling_note}</p>')
        placement_note = _placement_note(s.model)
        if placement_note:
            out.append(f'<p class="note">{placement_note}</p>')
        win = s.model.static_window if s.model is not None else None
        if win:
            rule = (
                f"markers' 90th-percentile speed ≤ "
                f"{1000 * float(win.get('still_below_m_s') or 0.0):.0f} mm/s"
                + ("" if win.get("plates_loaded") is None
                   else f", {win.get('plates_loaded')} plates loaded")
            )  # fmt: skip
            if win.get("judged") is False:
                part = "the whole trial (too short to judge whether it moves)"
            elif win.get("whole_trial"):
                part = f"the whole trial, still throughout ({rule})"
            else:
                part = (
                    f"{win.get('start_s', 0.0):.2f}–{win.get('end_s', 0.0):.2f} s "
                    f"({win.get('frames')} of {win.get('of_frames')} frames), its longest "
                    f"still, double-stance part ({rule})"
                )
            out.append(
                '<p class="note">Static trial used for scaling and marker placement: '
                f"{_e(part)}.</p>"
            )
    rows = []
    for r in s.stages or ():
        cls = ' class="na"' if r.status in ("not available", "failed") else ""
        rows.append(
            [
                _e(r.name),
                f"<span{cls}>{_e(r.status)}</span>",
                _num(r.seconds, ".2f", "s"),
                _e(_or(r.message, "")),
            ]
        )
    out.append(_table(["stage", "status", "time", "note"], rows, "stages"))
    opt = s.optimization
    if opt:
        crit = f" ({_e(opt.criterion)})" if opt.criterion else ""
        out.append(f'<p class="note">Tension optimisation: {_e(opt.method)}{crit}.</p>')
        if opt.frames_solved:
            legs = ", ".join(f"{_e(k)} {int(v)}" for k, v in opt.frames_solved.items())
            out.append(
                f'<p class="note">Frames solved per leg (a leg whose foot stands off the '
                f"plates is left out, the other solved): {legs}.</p>"
            )
        if opt.kkt is not None:
            out.append(_kkt_table(opt.kkt))
        if opt.emg_gains:
            gst = opt.emg_gain_status or {}
            rows = [
                [_e(c), _num(g, ".3f"), _status_html(gst.get(c) or gain_status(g).value)]
                for c, g in opt.emg_gains.items()
            ]
            out.append(
                _table(
                    ["EMG channel", "gain g_c (activation per unit EMG)", "status"], rows, "gains"
                )
            )
    ver = s.versions
    out.append(
        _table(["software", "version"], [[_e(k), _e(v)] for k, v in ver.items()], "versions")
    )
    ins = s.inputs
    out.append(
        _table(
            ["input", "file", "sha256"],
            [[_e(i.role), _e(Path(i.path).name), _e(i.sha256[:16] + "…")] for i in ins],
            "inputs",
        )
    )
    return "".join(out)


def render_html(res: SessionResults, figures: Mapping[str, str] | None = None) -> str:
    """The report as one self-contained HTML string."""
    figs = build_figures(res) if figures is None else figures
    s = res.summary
    subj = s.subject
    na = s.not_available or ()
    # a session of FES trials only has no gait results: its report is the FES section
    gait = res.has("q") or not s.fes
    kind = "Gait analysis" if gait else "FES knee model"
    head = (
        f"<h1>{kind} report — {_e(subj.name)}"
        f"{', trial ' + _e(s.trial) if s.trial else ''}</h1>"
        f'<p class="note">Body mass {_num(subj.mass_kg, ".1f", "kg")}, height '
        f"{_num(subj.height_m, '.2f', 'm')}, side of interest {_e(subj.side)}. "
        f"Produced {_e(s.created_utc)} by msk "
        f"{_e(s.versions.get('msk', ''))}.</p>"
    )
    if na:
        head += (
            '<p class="warn"><b>Parts of the analysis are not available in this report:</b> '
            + "; ".join(f"{_e(i.stage)} ({_e(i.status)}: {_e(i.reason)})" for i in na)
            + "</p>"
        )
    flags = s.quality.flags or ()
    if flags:
        head += (
            f'<div class="warn" id="quality-flags"><b>Quality gates raised ({len(flags)}): '
            "these results must not be used without checking the quantities named "
            "here.</b><ul>"
            + "".join(
                f"<li>{_e(f.trial)}: {_e(f.message)} "
                f"[{_e(f.quantity)} = {_num(f.value)}, threshold "
                f"{_num(f.threshold)}]</li>"
                for f in flags
            )
            + "</ul></div>"
        )
    parts = [head]
    if gait:
        parts += [
            _strength_section(res, figs),
            _mass_section(res, figs),
            _gait_section(res, figs),
            _contact_section(res, figs),
            _quality_section(res),
        ]
    n = len(parts)
    if s.fes or any(i.stage == "fes" for i in na):
        parts.append(_fes_section(res, figs, n))
        n += 1
    parts.append(_methods_section(res, n, gait=gait))
    body = "".join(parts)
    cited = [k for k in range(1, len(REFERENCES) + 1) if f"[{k}]" in body]
    if cited:  # the works cited in this report, under their fixed numbers
        body += (
            '<h3 id="references">References</h3><ol class="refs">'
            + "".join(f'<li value="{k}">{_e(REFERENCES[k - 1])}</li>' for k in cited)
            + "</ol>"
        )
    title = f"msk report {_e(subj.name)}"

    return (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">{_CSP_META}'
        f"<title>{title}</title><style>{_CSS}</style></head>"
        f"<body><main>{body}</main></body></html>\n"
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
) -> Path:
    """Write ``report.html`` (and ``report.pdf`` when Chromium is available and ``pdf`` is not
    False; ``MSK_NO_PDF=1`` disables it) into ``folder``."""
    folder = Path(folder)
    path = folder / "report.html"
    # a private temporary file renamed into place: a symlink planted in a received folder (as
    # report.html, report.pdf or any temporary name) is replaced, never written through
    write_file_atomic(path, render_html(res, figures).encode("utf-8"))
    if pdf is None:
        pdf = os.environ.get("MSK_NO_PDF", "") not in ("1", "true", "yes")
    if pdf and not write_pdf(path, folder / "report.pdf"):
        # no stale report.pdf of earlier results beside the new report.html
        with contextlib.suppress(FileNotFoundError):
            os.unlink(folder / "report.pdf")
    return path
