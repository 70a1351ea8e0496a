"""msk.report.sections and msk.report.cycles on a synthetic walk with known events, stride and
curves: the spatiotemporal parameters and the cycle means recover the truth; the event source,
the static trial and the reference numbering are said as they are."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from msk.io.opensim_files import Table
from msk.report import render_html
from msk.report.cycles import curves_from_tables
from msk.report.references import Citations
from msk.report.sections import SECTIONS
from msk.report.sections.spatiotemporal import spatiotemporal_from_events
from msk.results.folder import SessionResults
from tests.support.summaries import BASE

T = 1.1  # stride time, s
SPEED = 1.2  # m/s
#: left strikes, left offs (60 %), right strikes (50 % later), right offs
LS, LO = (0.1, 1.2, 2.3), (0.76, 1.86)
RS, RO = (0.65, 1.75), (0.21, 1.31, 2.41)


def _walk(noise: float = 0.0, **extra: object) -> SessionResults:
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 2.6, 0.005)
    phase_l = 2 * np.pi * (t - LS[0]) / T
    cols = {
        "pelvis_tx": SPEED * t,
        "pelvis_tz": 0.01 * np.sin(phase_l),
        "pelvis_tilt": np.zeros_like(t),
        "knee_angle_l": -np.deg2rad(30.0) * (1 - np.cos(phase_l))
        + noise * rng.standard_normal(t.size),
        "knee_angle_r": -np.deg2rad(20.0) * (1 - np.cos(phase_l - np.pi)),
    }
    q = Table(t, np.column_stack(list(cols.values())), tuple(cols), "q")
    events = [
        {"label": label, "context": side, "time": x}
        for label, side, xs in (
            ("Foot Strike", "Left", LS),
            ("Foot Off", "Left", LO),
            ("Foot Strike", "Right", RS),
            ("Foot Off", "Right", RO),
        )
        for x in xs
    ]
    summary = {**BASE, "events": events, "gait_cycle_s": [LS[0], LS[1]], **extra}
    return SessionResults({"q": q}, summary, angle_columns=tuple(cols))


def test_the_registry_holds_one_section_per_key_in_the_clinical_order():
    keys = [s.key for s in SECTIONS]
    assert len(set(keys)) == len(keys)
    assert keys[:6] == [
        "session",
        "spatiotemporal",
        "kinematics",
        "kinetics",
        "knee_loads",
        "muscle_forces",
    ]
    assert keys.index("strength") < keys.index("mass") < keys.index("methods")
    assert keys[-1] == "references"
    assert [s.order for s in SECTIONS] == sorted(s.order for s in SECTIONS)


def test_spatiotemporal_parameters_equal_the_synthetic_truth():
    vals = spatiotemporal_from_events(_walk())
    left = vals["left"]
    assert len(left["stride_time_s"]) == 2
    np.testing.assert_allclose(left["stride_time_s"], T, rtol=1e-9)
    np.testing.assert_allclose(left["cadence_steps_per_min"], 120 / T, rtol=1e-9)
    np.testing.assert_allclose(left["stance_pct"], 60.0, rtol=1e-9)
    np.testing.assert_allclose(left["swing_pct"], 40.0, rtol=1e-9)
    np.testing.assert_allclose(left["double_support_pct"], 100 * 0.22 / T, rtol=1e-9)
    # the pelvis travels SPEED·T per stride (its small sideways sway returns every stride)
    np.testing.assert_allclose(left["stride_length_m"], SPEED * T, rtol=1e-3)
    np.testing.assert_allclose(left["walking_speed_m_s"], SPEED, rtol=1e-3)
    np.testing.assert_allclose(vals["right"]["stride_time_s"], T, rtol=1e-9)
    assert np.isnan(left["step_width_m"]).all()  # needs the feet: not made up


def test_cycle_means_recover_the_curve_and_its_foot_off():
    curves = curves_from_tables(_walk())
    assert curves is not None and curves.left.n_cycles == 2 and curves.right.n_cycles == 1
    pct = np.linspace(0, 100, 101)
    truth = 30.0 * (1 - np.cos(2 * np.pi * pct / 100))  # knee flexion, deg
    # linear interpolation of 5-ms samples: within 0.01°
    np.testing.assert_allclose(curves.left.mean("knee_flexion_deg"), truth, atol=0.01)
    np.testing.assert_allclose(curves.left.sd("knee_flexion_deg"), 0.0, atol=1e-9)
    np.testing.assert_allclose(curves.left.foot_off_pct, 60.0)
    assert curves.right.sd("knee_flexion_deg") is None  # one cycle: no SD
    noisy = curves_from_tables(_walk(noise=np.deg2rad(1.0)))
    assert noisy is not None
    sd = noisy.left.sd("knee_flexion_deg")
    assert sd is not None and 0.2 < float(np.mean(sd)) < 3.0  # 1° noise, two cycles


@pytest.mark.parametrize(
    ("source", "words"),
    [("plates", "force plates"), ("file", "C3D events"), ("kinematics", "marker kinematics")],
)
def test_the_event_source_is_the_summarys(source, words):
    sources = {"left foot strike": source, "left foot off": source, "notes": []}
    html = render_html(_walk(event_sources=sources), figures={})
    assert f"strikes from {words}" in html
    if source != "file":
        assert "(C3D events)" not in html and "C3D events" not in html


def test_methods_mention_a_static_trial_only_when_there_is_one():
    html = render_html(_walk(), figures={})  # BASE: a task trial only
    methods = html.split('<section id="methods">')[1]
    assert "static trial" in methods and "no static trial" in methods
    assert "placed from the static trial" not in methods
    static = {"role": "static", "path": "s.c3d", "sha256": "2" * 64, "bytes": 1}
    window = {"whole_trial": True, "still_below_m_s": 0.03, "judged": True}
    res = _walk(inputs=[*BASE["inputs"], static], model={"static_window": window})
    methods = render_html(res, figures={}).split('<section id="methods">')[1]
    assert "placed from the static trial" in methods and "Static trial used" in methods


def test_references_are_numbered_consecutively_in_citation_order():
    c = Citations()
    assert c.cite("hicks2015") == "[1]"
    assert c.cite("kutzner2010", "fregly2012") == "[2, 3]"
    assert c.cite("hicks2015") == "[1]"
    assert [k for k, _ in c.cited] == [1, 2, 3]
    assert c.cited[1][1].startswith("Kutzner I") and "(2010)" in c.cited[1][1]
    with pytest.raises(KeyError):
        c.cite("nobody1999")
    html = render_html(_walk(), figures={})
    refs = re.findall(r'<li value="(\d+)">', html)
    assert refs == [str(k) for k in range(1, len(refs) + 1)] and refs


def test_sections_are_numbered_without_gaps():
    html = render_html(_walk(), figures={})
    numbers = [int(n) for n in re.findall(r"<h2>(\d+)\. ", html)]
    assert numbers == list(range(1, len(numbers) + 1))


def test_one_report_pools_every_task_trial():
    a, b = _walk(trial="walk1"), _walk(noise=np.deg2rad(1.0), trial="walk2")
    html = render_html(a, figures={}, trials=[a, b])
    assert "trials walk1, walk2" in html
    assert '<span class="left">left</span> 4 cycle(s)' in html  # 2 + 2 left cycles
    assert "<svg" in html  # the grids redrawn from the pooled cycles
    single = render_html(a, figures={})
    assert '<span class="left">left</span> 2 cycle(s)' in single


def test_msk_report_on_the_folder_of_task_trial_folders_writes_one_report(tmp_path, capsys):
    from msk.cli import main
    from msk.results.folder import write_session

    for name, noise in (("walk1", 0.0), ("walk2", np.deg2rad(1.0))):
        write_session(tmp_path / "s" / name, _walk(noise=noise, trial=name))
    assert main(["report", str(tmp_path / "s")]) == 0
    html = (tmp_path / "s" / "report.html").read_text(encoding="utf-8")
    assert "trials walk1, walk2" in html and "4 cycle(s)" in html
    assert capsys.readouterr().out.strip().endswith("report.html")


def test_knee_section_states_the_patellofemoral_peak():
    """With the patellar tendon the knee section gives the patellofemoral force's peak per
    variant (summary ``knee_loads``); without it, no such line."""
    loads = {"joint": "knee_l", "patella": "tendon",
             "peak_patellofemoral_n": {"generic": 950.0},
             "peak_patellofemoral_bw": {"generic": 1.234}}  # fmt: skip
    res = _walk(knee_loads=loads)
    html = render_html(res, figures={"contact": "<svg></svg>"})
    line = html.split('<section id="knee-loads">')[1].split("</section>")[0]
    assert "Patellofemoral contact force" in line and "generic parameters 1.23 BW" in line
    plain = render_html(_walk(), figures={"contact": "<svg></svg>"})
    assert "Patellofemoral" not in plain


def test_the_spatiotemporal_table_shows_the_norm_and_marks_a_side_beyond_2_sd():
    """The norm column holds the set's scalar mean ± SD; a side's mean beyond ±2 SD (here the
    synthetic 1.2 m/s against 1.45 ± 0.1) is marked ▼ and coloured, one inside (cadence
    109.1 against 110 ± 8) is not; a set without scalars leaves the column empty, said."""
    from msk.gait.norms import NormativeBands
    from msk.report.sections.spatiotemporal import norm_position

    pct = np.linspace(0, 100, 101)
    norms = NormativeBands(
        ("knee_flexion_deg",), pct[:, None] * 0.0, pct[:, None] * 0.0 + 1.0, "adults (n = 9)",
        "synthetic", "CC0-1.0",
        scalars={"walking_speed_m_s": (1.45, 0.1), "cadence_steps_per_min": (110.0, 8.0)},
    )  # fmt: skip
    html = render_html(_walk(), figures={}, norms=norms)
    table = html.split('<section id="spatiotemporal">')[1].split("</table>")[0]
    speed = next(r for r in table.split("<tr>") if "walking speed" in r)
    cadence = next(r for r in table.split("<tr>") if "cadence" in r)
    assert "1.45 ± 0.10" in speed and speed.count('class="out low"') == 2 and "▼" in speed
    assert "110.0 ± 8.0" in cadence and "out" not in cadence
    assert "more than 2 SD" in html and "sessions' stride means" not in html
    few = dataclasses.replace(norms, notes={"n_sessions_spatiotemporal": "2"})
    assert "SD between its 2 sessions' stride means, itself uncertain" in render_html(
        _walk(), figures={}, norms=few
    )
    assert norm_position([1.2, 1.2], (1.45, 0.1)) == "low"
    assert norm_position([1.7], (1.45, 0.1)) == "high"
    assert norm_position([1.5], (1.45, 0.1)) == ""
    assert norm_position([1.7], (1.45, float("nan"))) == ""  # no SD: no flag
    plain = NormativeBands(("knee_flexion_deg",), pct[:, None] * 0.0, pct[:, None] * 0.0,
                           "adults", "s", "l")  # fmt: skip
    html = render_html(_walk(), figures={}, norms=plain)
    assert "holds no spatiotemporal values" in html and 'class="out' not in html


def test_the_kinematics_say_the_pelvis_frame_of_the_angles():
    note = (
        "pelvis angles in the plane of the ASIS (RASI, LASI) and the mid-PSIS (RPSI, LPSI) "
        "markers (Plug-in Gait's pelvis): its tilt is the model's pelvis body frame's +3.2°"
    )
    html = render_html(_walk(gait={"notes": [note]}), figures={})
    kin = html.split('<section id="kinematics">')[1].split("</section>")[0]
    assert "Pelvis angles in the pelvis frame of Plug-in Gait" in kin and "+3.2°" in kin
    assert "Davis RB" in html  # cited, in the references
    assert "pelvis frame of Plug-in Gait" not in render_html(_walk(), figures={})


def test_the_kinematics_say_how_the_hip_and_knee_angles_are_defined():
    notes = [
        "hip angles: the thigh relative to the pelvis frame of the pelvis angles (Plug-in "
        "Gait's YXZ Cardan sequence), not the model's hip coordinates",
        "right knee flexion as Plug-in Gait measures it: Plug-in Gait's knee centre (chord)",
        "the model's knee has no adduction or rotation degree of freedom",
    ]
    html = render_html(_walk(gait={"notes": notes}), figures={})
    kin = html.split('<section id="kinematics">')[1].split("</section>")[0]
    assert "Hip angles: the thigh relative to the pelvis frame" in kin
    assert "Right knee flexion as Plug-in Gait measures it" in kin
    assert "Hip angles:" not in render_html(_walk(), figures={})


def test_strength_section_shows_the_pooled_groups_identified_first_and_never_a_bound():
    """The session's pooled strength (summary ``pooled_strength``): the identified group with
    its moment (N·m, N·m/kg over the subject's mass) and factor interval; each other group
    with its reason and the test that would determine it, and no moment or F_iso; a group on
    a bound written "identified" is listed as at bound, not in the identified table."""
    from msk.pipeline.pooled_strength import pooled_summary
    from tests.pipeline.test_pooled_strength import _record

    ps = pooled_summary(_record()).to_dict()
    html = render_html(_walk(pooled_strength=ps), figures={})
    sec = html.split('<section id="strength">')[1].split("</section>")[0]
    table, rest = sec.split("Not identified: why")
    assert "knee_extensors" in table and "210 N·m" in table and "3.00 N·m/kg" in table
    assert "1.20 × [1.05–1.35]" in table
    assert "plantar_flexors" not in table and "99 N·m" not in sec
    assert "<b>plantar_flexors</b> (at bound)" in rest
    assert "<b>dorsiflexors</b> (not determined): dorsiflexors: reason in plain words" in rest
    assert "isometric MVC of ankle dorsiflexion" in rest
    assert "<b>hamstrings</b> (not determined): its EMG channel failed a check" in rest
    assert "1 of 4 muscle groups identified" in sec


def test_the_knee_section_says_which_strength_the_subject_specific_prediction_took():
    """``strength.applied_groups`` empty: the subject-specific prediction is the generic one,
    said once and its patellofemoral peak not repeated; with identified groups, they are
    named; an older summary without the field says nothing."""
    from types import SimpleNamespace

    from msk.report.sections.knee_loads import _applied, _patellofemoral

    assert "is the generic one" in (_applied(SimpleNamespace(applied_groups=())) or "")
    named = _applied(SimpleNamespace(applied_groups=("vaslat", "rf"))) or ""
    assert "vaslat, rf" in named and "generic strength" in named
    assert _applied(SimpleNamespace(applied_groups=None)) is None and _applied(None) is None
    loads = SimpleNamespace(peak_patellofemoral_bw={"generic": 0.71, "subject_specific": 0.7})
    both = _patellofemoral(loads) or ""
    assert "generic parameters 0.71 BW" in both and "subject-specific 0.70 BW" in both
    assert "subject-specific" not in (_patellofemoral(loads, generic_only=True) or "")
