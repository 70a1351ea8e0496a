"""The report's figures, inline SVG written directly (:mod:`msk.report.svg`): gait-cycle grids
(left red, right green, mean ± SD, normative grey band, foot-off lines), knee loads with the
in-vivo walking range, muscle forces, strength factors and curves, segment masses, the FES
cross-validation trial."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from msk.gait.norms import NormativeBands
from msk.report import svg
from msk.report.cycles import (
    KINEMATICS,
    KINETICS,
    PERCENT,
    CycleCurves,
    Variable,
    curves_from_tables,
)
from msk.report.format import STATUS_COLOURS, escape_text, finite, group_statuses
from msk.results.folder import SessionResults

__all__ = [
    "FIGURES",
    "KNEE_WALKING_PEAK_BW",
    "SIDE_COLOURS",
    "build_figures",
    "cycle_grid",
    "kinematics_figure",
    "kinetics_figure",
]

#: left red, right green (the clinical gait report convention)
SIDE_COLOURS = {"left": "#c62828", "right": "#2e7d32"}
NORM_COLOUR = "#9e9e9e"
#: in-vivo peak tibiofemoral contact force in level walking, BW: 2.61 BW mean of five subjects
#: with instrumented prostheses (Kutzner et al. 2010); 2–3 BW across them and the Grand Challenge
#: subjects (Fregly et al. 2012)
KNEE_WALKING_PEAK_BW = (2.0, 3.0)
#: Plausible strength-factor range (× generic F_iso): the EMG-driven vs OpenSim thesis, Table 3.1
FACTOR_RANGE = (0.5, 2.0)


def cycle_grid(
    curves: CycleCurves,
    variables: Sequence[Variable | None],
    label: str,
    norms: NormativeBands | None = None,
) -> str | None:
    """A grid of panels, one per variable (3 columns; None an empty cell): each side's mean ±
    SD over its cycles, the normative mean ± SD in grey where ``norms`` has the variable, each
    side's mean foot off as a dashed vertical line."""
    panels: list[svg.Panel | None] = []
    for v in variables:
        if v is None:
            panels.append(None)
            continue
        p = svg.Panel(title=v.title, xlabel="gait cycle (%)", ylabel=f"({v.unit})", xlim=(0, 100))
        if norms is not None and v.key in norms.variables:
            n_mean, n_sd = norms.band(v.key)
            p.band(
                PERCENT,
                n_mean - n_sd,
                n_mean + n_sd,
                NORM_COLOUR,
                "normative mean ± SD",
                opacity=0.35,
            )
        for side in ("left", "right"):
            sc = curves.side(side)
            m = sc.mean(v.key)
            if m is None:
                continue
            col = SIDE_COLOURS[side]
            sd = sc.sd(v.key)
            n = sc.cycles_with(v.key)
            if sd is not None:
                p.band(PERCENT, m - sd, m + sd, col, f"{side} ± SD", opacity=0.18)
            p.line(PERCENT, m, col, f"{side} mean" if n > 1 else f"{side} (one cycle)")
            off = sc.foot_off_pct[np.isfinite(sc.foot_off_pct)]
            if off.size:
                p.vline(float(off.mean()), col, f"{side} foot off")
        if p.empty:
            known = any(v.key in curves.side(s).values for s in ("left", "right"))
            p.note = "no measured cycle" if known else "not computed for this model"
        panels.append(p)
    return svg.grid(panels, 3, label=label, panel_w=300.0, panel_h=200.0)


def kinematics_figure(curves: CycleCurves, norms: NormativeBands | None = None) -> str | None:
    return cycle_grid(curves, KINEMATICS, "kinematics", norms)


def kinetics_figure(curves: CycleCurves, norms: NormativeBands | None = None) -> str | None:
    return cycle_grid(curves, KINETICS, "kinetics", norms)


def _fig_kinematics(res: SessionResults, curves: CycleCurves | None) -> str | None:
    return None if curves is None else kinematics_figure(curves)


def _fig_kinetics(res: SessionResults, curves: CycleCurves | None) -> str | None:
    return None if curves is None else kinetics_figure(curves)


def _cycle_axis(res: SessionResults, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """x values in % of the side of interest's gait cycle and the in-cycle mask."""
    cyc = res.summary.gait_cycle_s
    if cyc:
        x = 100.0 * (t - cyc[0]) / (cyc[1] - cyc[0])
        return x, (x >= 0) & (x <= 100), "gait cycle (%)"
    return t, np.ones(t.size, dtype=bool), "time (s)"


def _fig_joints(res: SessionResults, curves: CycleCurves | None) -> str | None:
    """Without a gait cycle: the side of interest's hip, knee and ankle angles, moments and
    powers against time."""
    if curves is not None or not res.has("q"):
        return None
    sfx = "_l" if res.summary.subject.side == "left" else "_r"
    q = res.table("q")
    x, sel, xl = _cycle_axis(res, q.time)
    tq = res.table("joint_torques") if res.has("joint_torques") else None
    mass = res.summary.subject.mass_kg or 1.0
    rows: list[list[svg.Panel | None]] = [[], [], []]
    for stem, sign, title in (
        ("hip_flexion", 1.0, "Hip flexion"),
        ("knee_angle", -1.0, "Knee flexion"),
        ("ankle_angle", 1.0, "Ankle dorsiflexion"),
    ):
        c = stem + sfx
        pa = svg.Panel(title=title, xlabel=xl, ylabel="angle (deg)")
        pm = svg.Panel(title=f"{title} moment", xlabel=xl, ylabel="moment (N·m/kg)")
        pp = svg.Panel(title=title.split()[0] + " power", xlabel=xl, ylabel="power (W/kg)")
        if c in q.columns:
            ang = q.column(c)
            pa.line(x[sel], sign * np.rad2deg(ang[sel]), "#1565c0", "this session")
            if tq is not None and c in tq.columns and q.time.size > 1:
                tau = np.interp(q.time, tq.time, tq.column(c))
                pm.line(x[sel], sign * tau[sel] / mass, "#c62828", "net joint moment")
                power = tau * np.gradient(ang, q.time)
                pp.line(x[sel], power[sel] / mass, "#2e7d32", "joint power")
        for r, p in enumerate((pa, pm, pp)):
            rows[r].append(p)
    return svg.grid([p for r in rows for p in r], 3, label="joints", panel_w=300.0, panel_h=200.0)


def _fig_knee_loads(res: SessionResults, curves: CycleCurves | None) -> str | None:
    if not res.has("knee_contact"):
        return None
    kc = res.table("knee_contact")
    x, sel, xl = _cycle_axis(res, kc.time)
    comps = [c for c in ("total", "medial", "lateral") if f"generic_{c}_bw" in kc.columns]
    cmp = res.summary.comparison
    agree = cmp.knee_contact("generic") if cmp else None
    axial = bool(agree and agree.component == "axial total" and "generic_axial_bw" in kc.columns)
    style = {
        "measured": ("#000000", None, "measured (instrumented implant)"),
        "generic": ("#757575", "5 3", "predicted, generic parameters"),
        "subject_specific": ("#1565c0", None, "predicted, subject-specific"),
    }
    lo, hi = KNEE_WALKING_PEAK_BW
    panels: list[svg.Panel | None] = []
    for comp in comps:
        title = "total (axial)" if comp == "total" and axial else comp
        p = svg.Panel(
            title=title,
            xlabel=xl,
            ylabel="knee contact force (body weights)",
            xlim=(0.0, 100.0) if xl == "gait cycle (%)" else None,
        )
        if comp == "total":
            p.span(lo, hi, "#ffe0b2", f"in-vivo walking peaks {lo:g}–{hi:g} BW")
        for key, (c, dash, lab) in style.items():
            pred = "axial" if comp == "total" and axial and key != "measured" else comp
            col = f"{key}_{pred}_bw"
            if col in kc.columns:
                p.line(x[sel], kc.column(col)[sel], c, lab, dash=dash)
        panels.append(p)
    return svg.grid(panels, 3, label="knee contact force", panel_w=300.0, panel_h=220.0)


#: leg muscles by the stems of their names: every muscle of the lower limb models msk ships
_NOT_LEG = ("ercspn", "extobl", "intobl", "lumbar", "abd", "trunk", "torso", "reserve")


def _fig_muscles(res: SessionResults, curves: CycleCurves | None) -> str | None:
    """The 8 largest leg-muscle forces of the side of interest over its cycle."""
    if not res.has("muscle_forces"):
        return None
    sfx = "_l" if res.summary.subject.side == "left" else "_r"
    mf = res.table("muscle_forces")
    x, sel, xl = _cycle_axis(res, mf.time)
    idx = [
        k
        for k, c in enumerate(mf.columns)
        if c.endswith(sfx) and not c.lower().startswith(_NOT_LEG)
    ]
    if not idx:
        return None
    with np.errstate(all="ignore"):
        peaks = np.nan_to_num(np.nanmax(np.abs(mf.data[:, idx]), axis=0, initial=0.0))
    top = [idx[k] for k in np.argsort(peaks)[::-1][:8]]
    palette = (
        "#1565c0",
        "#c62828",
        "#2e7d32",
        "#ef6c00",
        "#6a1b9a",
        "#00838f",
        "#5d4037",
        "#ad1457",
    )
    p = svg.Panel(
        title="8 largest",
        xlabel=xl,
        ylabel="muscle force (N)",
        xlim=(0.0, 100.0) if xl == "gait cycle (%)" else None,
    )
    for k, c in zip(top, palette):
        p.line(x[sel], mf.data[sel, k], c, mf.columns[k])
    return svg.grid([p], 1, label="muscle forces", panel_w=760.0, panel_h=260.0)


def _fig_strength(res: SessionResults, curves: CycleCurves | None) -> str | None:
    st = res.summary.strength
    if not st or not st.groups:
        return None
    rows = []
    for g, status in zip(st.groups, group_statuses(st)):
        col = STATUS_COLOURS[status]
        interval = status != "prior" and finite(g.ci_low) and finite(g.ci_high)
        rows.append(
            (
                g.group,
                g.factor,
                g.ci_low if interval else None,
                g.ci_high if interval else None,
                col,
                status == "identified",
            )
        )
    lo, hi = FACTOR_RANGE
    chart = svg.Intervals(
        rows,
        "strength factor (× generic F_iso, dimensionless)",
        (0.3, 2.2),
        reference=(1.0, "generic model"),
        span=(lo, hi, "#e3f2fd"),
        legend=[
            ("band", "#e3f2fd", f"plausible range {lo}–{hi} ×"),
            ("vline", "#000000", "generic model (1.0 ×)"),
        ]
        + [("marker", c, w) for w, c in STATUS_COLOURS.items()],
    )
    return chart.svg("strength factors")


def _fig_strength_curves(res: SessionResults, curves: CycleCurves | None) -> str | None:
    st = res.summary.strength
    js = st.joint_strength if st else None
    acts = (js.actions if js else None) or ()
    mass = js.mass_kg if js else None
    if not acts or not finite(mass) or mass <= 0:
        return None
    panels: list[svg.Panel | None] = []
    for a in acts:
        x = np.asarray(a.angles_deg, dtype=float)
        p = svg.Panel(title=a.action, xlabel=f"{a.angle_label} (deg)", ylabel="moment (N·m/kg)")
        p.line(
            x, np.asarray(a.generic_nm, dtype=float) / mass, "#000000", "generic model", dash="5 3"
        )
        word = a.status or "prior"
        if word == "identified":
            p.line(
                x,
                np.asarray(a.identified_nm, dtype=float) / mass,
                STATUS_COLOURS[word],
                "identified (this subject)",
                width=2.0,
            )
        else:
            p.note = "= generic (prior)" if word == "prior" else f"identified: {word}"
        panels.append(p)
    return svg.grid(
        panels, min(4, len(panels)), label="joint strength", panel_w=235.0, panel_h=190.0
    )


def _fig_mass(res: SessionResults, curves: CycleCurves | None) -> str | None:
    ident = res.summary.identification
    if not ident:
        return None
    anth = res.summary.anthropometry
    table = {} if anth is None else {k: v.mass_kg for k, v in anth.segments.items()}
    segs = ident.segments
    tab: list[float | None] = []
    for s in segs:
        n = s.name
        key = n
        if n.startswith(("talus", "calcn", "toes")):
            key = "foot" + n[-2:]
        elif n.startswith("femur"):
            key = "femur" + n[-2:]
        v = table.get(key) if n.startswith(("pelvis", "femur", "tibia", "torso", "calcn")) else None
        tab.append(v)
    chart = svg.Bars(
        [s.name for s in segs],
        [
            ("scaled generic model", [s.prior_mass_kg for s in segs], "#cfd8dc", []),
            (
                "estimated (±2 SD), coloured by status",
                [s.mass_kg for s in segs],
                [STATUS_COLOURS[s.status_word()] for s in segs],
                [2 * (s.mass_std_kg or 0.0) for s in segs],
            ),
            ("anthropometric table (Dumas 2007)", tab, "hatch", []),
        ],
        "segment mass (kg)",
        extra_legend=[("band", c, f"status: {w}") for w, c in STATUS_COLOURS.items()],
    )
    return chart.svg("segment masses")


def _fig_fes(res: SessionResults, curves: CycleCurves | None) -> str | None:
    if not res.has("fes_validation"):
        return None
    tb = res.table("fes_validation")
    p = svg.Panel(
        title="Cross-validation trial (stimulation pattern not used for identification)",
        xlabel="time (s)",
        ylabel="knee angle (deg, 0 = full extension)",
    )
    p.line(
        tb.time, np.rad2deg(tb.column("knee_angle_measured")), "#000000", "measured (goniometer)"
    )
    p.line(
        tb.time,
        np.rad2deg(tb.column("knee_angle_simulated")),
        "#1565c0",
        "simulated, identified model",
    )
    if "knee_angle_simulated_k_s0" in tb.columns:
        p.line(
            tb.time,
            np.rad2deg(tb.column("knee_angle_simulated_k_s0")),
            "#ef6c00",
            "simulated before k_s identification",
            dash="5 3",
        )
    return svg.grid([p], 1, label="FES cross-validation", panel_w=760.0, panel_h=260.0)


FIGURES: tuple[tuple[str, Callable[[SessionResults, CycleCurves | None], str | None]], ...] = (
    ("kinematics", _fig_kinematics),
    ("kinetics", _fig_kinetics),
    ("joints", _fig_joints),
    ("contact", _fig_knee_loads),
    ("muscles", _fig_muscles),
    ("strength", _fig_strength),
    ("strength_curves", _fig_strength_curves),
    ("mass", _fig_mass),
    ("fes", _fig_fes),
)


def build_figures(res: SessionResults) -> dict[str, str]:
    """Inline SVG figures by name (:data:`FIGURES`); a figure that cannot be drawn is a
    one-line note in its place, never a lost report."""
    try:
        curves = curves_from_tables(res)
    except Exception:  # the grids then say so; the other figures are drawn
        curves = None
    out = {}
    for name, fn in FIGURES:
        try:
            text = fn(res, curves)
        except Exception as exc:
            text = (
                '<p class="warn">This figure could not be drawn ('
                + escape_text(f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}")
                + "); the tables hold its numbers.</p>"
            )
        if text:
            out[name] = text
    return out
