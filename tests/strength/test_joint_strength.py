"""Maximal isometric joint-moment curves (msk.strength.joint_strength, issue 17)."""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from msk.datasets.shared import REPO_ROOT
from msk.exceptions import ModelError
from msk.model.files import load_model
from msk.strength import (
    ACTIONS,
    JointStrengthCurves,
    action_status,
    max_isometric_moment_curves,
    with_strength,
)

KNEE_EXTENSORS = ("rect_fem_r", "vas_med_r", "vas_int_r", "vas_lat_r")


#: the keys every summary.json has (msk.results.summary.Summary's required ones) besides subject,
# quality
BASE_SUMMARY = {
    "session": "X",
    "created_utc": "2026-01-01T00:00:00Z",
    "versions": {"msk": "0.1.0"},
    "config": {"path": "x.toml", "sha256": "0" * 64},
    "inputs": [],
    "settings": {},
}


@pytest.fixture(scope="module")
def model():
    return load_model(REPO_ROOT / "msk" / "data" / "models" / "gait2392.toml")


@pytest.fixture(scope="module")
def curves(model) -> JointStrengthCurves:
    return max_isometric_moment_curves(model, side="right")


def test_every_action_is_positive_in_its_direction_with_plausible_magnitudes(curves):
    assert set(curves.actions) == set(ACTIONS)
    for c in curves.curves.values():
        assert np.all(c.moment_nm >= 0.0) and c.peak_nm > 0.0, c.action
        assert c.contributions_nm is not None
        np.testing.assert_allclose(c.contributions_nm.sum(axis=1), c.moment_nm, rtol=1e-12)
    # generic gait2392 knee extension: textbook order 150–300 N·m, peak in mid-range flexion
    # (gait2392 peaks at ~30° flexion, earlier than the ~60° of adult dynamometry)
    ke = curves["knee extension"]
    assert 150.0 <= ke.peak_nm <= 300.0
    assert 15.0 <= ke.peak_angle_deg <= 70.0
    assert set(KNEE_EXTENSORS) <= set(ke.muscles)
    assert not {"semimem_r", "bifemsh_r", "med_gas_r"} & set(ke.muscles)  # antagonists silent
    kf = curves["knee flexion"]
    assert {"semimem_r", "bifemsh_r"} <= set(kf.muscles) and "vas_lat_r" not in kf.muscles
    assert 50.0 <= kf.peak_nm <= ke.peak_nm
    pf, df = curves["ankle plantarflexion"], curves["ankle dorsiflexion"]
    assert "soleus_r" in pf.muscles and "tib_ant_r" in df.muscles
    assert pf.peak_nm > 2.0 * df.peak_nm  # plantarflexors are the strongest ankle group
    assert "psoas_r" in curves["hip flexion"].muscles
    assert "glut_max1_r" in curves["hip extension"].muscles
    assert "glut_med2_r" in curves["hip abduction"].muscles
    assert all(m.endswith("_r") for c in curves.curves.values() for m in c.muscles)


def test_left_side_mirrors_right(model, curves):
    left = max_isometric_moment_curves(model, side="left", joints=["knee"])
    np.testing.assert_allclose(
        left["knee extension"].moment_nm, curves["knee extension"].moment_nm, rtol=1e-6
    )
    assert set(left.actions) == {"knee extension", "knee flexion"}


@pytest.mark.parametrize("s", [0.5, 1.7])
def test_scaling_every_f_iso_scales_the_curves(model, curves, s):
    scaled = model.with_strength({m.name: s for m in model.muscles})
    got = max_isometric_moment_curves(scaled, side="right")
    for a in curves.actions:
        np.testing.assert_allclose(got[a].moment_nm, s * curves[a].moment_nm, rtol=1e-12)


def test_knee_extensor_factor_scales_the_knee_extension_curve_exactly(model, curves):
    f = 1.6
    strong = with_strength(model, dict.fromkeys(KNEE_EXTENSORS, f))
    got = max_isometric_moment_curves(strong, side="right", joints=["knee extension"])
    base = curves["knee extension"]
    # only the quadriceps scale: the other agonists (sartorius, TFL) stay generic
    ii = [base.muscles.index(m) for m in KNEE_EXTENSORS]
    other = np.delete(base.contributions_nm, ii, axis=1).sum(axis=1)
    quad = base.contributions_nm[:, ii].sum(axis=1)
    np.testing.assert_allclose(got["knee extension"].moment_nm, f * quad + other, rtol=1e-12)
    # and the whole knee-extensor group (every agonist of the action) by exactly f
    every = with_strength(model, dict.fromkeys(base.muscles, f))
    got = max_isometric_moment_curves(every, side="right", joints=["knee extension"])
    np.testing.assert_allclose(got["knee extension"].moment_nm, f * base.moment_nm, rtol=1e-12)


def test_activation_scales_linearly_and_grid_is_honoured(model, curves):
    grid = [0.0, 45.0, 90.0]
    got = max_isometric_moment_curves(
        model, side="r", joints=["knee extension"], angles_deg={"knee extension": grid},
        activation=0.5,
    )  # fmt: skip
    c = got["knee extension"]
    assert c.angles_deg.tolist() == grid and c.angle_label == "knee flexion"
    full = curves["knee extension"]
    idx = [list(full.angles_deg).index(a) for a in grid]
    np.testing.assert_allclose(c.moment_nm, 0.5 * full.moment_nm[idx], rtol=1e-12)


def test_errors(model):
    with pytest.raises(ModelError, match="side"):
        max_isometric_moment_curves(model, side="middle")
    with pytest.raises(ModelError, match="unknown joint action"):
        max_isometric_moment_curves(model, side="right", joints=["elbow"])
    with pytest.raises(ModelError, match="activation"):
        max_isometric_moment_curves(model, side="right", activation=0.0)
    with pytest.raises(ModelError, match="not computed"):
        max_isometric_moment_curves(
            model, side="right", joints=["knee"], angles_deg={"hip flexion": [0.0]}
        )


def test_summary_record_is_json_and_per_kg(curves):
    rec = json.loads(json.dumps(curves.as_dict(mass_kg=80.0)))
    ke = next(a for a in rec["actions"] if a["action"] == "knee extension")
    assert ke["peak_nm_per_kg"] == pytest.approx(ke["peak_nm"] / 80.0)
    assert len(ke["moment_nm_per_kg"]) == len(ke["angles_deg"])
    hip = next(a for a in rec["actions"] if a["action"] == "hip flexion")
    assert hip["posture_deg"] == {"knee_angle_r": -60.0}


def test_action_status_follows_the_groups_carrying_the_moment(curves):
    ke = curves["knee extension"]
    groups = {m: "quads" for m in KNEE_EXTENSORS}
    assert action_status(ke, groups, {"quads": "identified"})[0] == "identified"
    assert action_status(ke, groups, {"quads": "at bound"})[0] == "not determined"
    assert action_status(ke, groups, {"quads": "not determined"})[0] == "not determined"
    assert action_status(ke, {}, {})[0] == "prior"
    word, shares = action_status(ke, groups, {"quads": "prior"})
    assert word == "prior" and shares["quads"] > 0.8 and sum(shares.values()) == pytest.approx(1)
    # a group with a negligible share of the peak does not decide the action's status
    tiny = {"tfl_r": "tfl", **groups}
    assert action_status(ke, tiny, {})[1]["tfl"] < 0.05
    assert action_status(ke, tiny, {"quads": "identified", "tfl": "at bound"})[0] == "identified"
    with pytest.raises(ModelError):
        action_status(replace(ke, contributions_nm=None), groups, {})


def _profile(model, groups: dict[str, tuple[str, ...]], factors, ci):
    """A StrengthProfile with given group factors and bootstrap intervals (fit r² 0.9)."""
    from msk.strength import StrengthProfile

    names = tuple(m.name for m in model.muscles)
    gnames = tuple(groups)
    f = np.asarray(factors, dtype=float)
    mg = tuple(next((g for g in gnames if n in groups[g]), "") for n in names)
    mf = np.array([f[gnames.index(g)] if g else 1.0 for g in mg])
    fiso = np.array([m.max_isometric_force for m in model.muscles])
    lo, hi = (np.array([c[k] for c in ci], dtype=float) for k in (0, 1))
    g = len(gnames)
    return StrengthProfile(
        group_names=gnames, factors=f, f_iso_generic=np.ones(g), f_iso=f, ci_low=lo,
        ci_high=hi, ci_cov_low=lo, ci_cov_high=hi, std_error=np.full(g, 0.05),
        identified=np.ones(g, dtype=bool), muscle_names=names, muscle_groups=mg,
        muscle_factors=mf, muscle_f_iso=fiso * mf, coordinate_names=("knee_angle_r",),
        residual=np.zeros(1), r2=0.9, r2_per_coordinate=np.array([0.9]), gate_threshold=0.3,
        gating_r=np.zeros((1, g, 1)), window_r=np.zeros((1, 1)),
        selected=np.ones((1, 1), dtype=bool), window_labels=np.zeros(1, dtype=np.int64),
        confidence=0.95, n_samples=100, n_bootstrap=200, method="test",
    )  # fmt: skip


def test_summary_record_and_report_keep_undetermined_curves_out(model, curves):
    from msk.report import build_figures, render_html
    from msk.results.folder import SessionResults
    from msk.strength import joint_strength_summary

    groups = {"quads": KNEE_EXTENSORS, "soleus": ("soleus_r",)}
    # quadriceps identified (1.3 ×, interval inside the bounds); soleus at the upper bound
    prof = _profile(model, groups, [1.3, 2.0], [(1.2, 1.4), (1.8, 2.0)])
    assert prof.statuses() == ("identified", "at bound")
    rec = json.loads(json.dumps(joint_strength_summary(model, prof, side="right", mass_kg=75.0)))
    acts = {a["action"]: a for a in rec["actions"]}
    assert rec["norms"] is None and "norms" in rec["norms_note"]
    ke = acts["knee extension"]
    assert ke["status"] == "identified" and ke["groups"][0]["group"] == "quads"
    np.testing.assert_allclose(ke["generic_nm"], curves["knee extension"].moment_nm)
    assert 1.0 < ke["identified_peak_nm"] / ke["generic_peak_nm"] <= 1.3
    assert acts["ankle plantarflexion"]["status"] == "not determined"
    assert acts["ankle dorsiflexion"]["status"] == "prior"
    assert acts["ankle dorsiflexion"]["identified_nm"] == acts["ankle dorsiflexion"]["generic_nm"]

    summary = {
        **BASE_SUMMARY,
        "subject": {"name": "X", "mass_kg": 75.0, "height_m": 1.7, "side": "right"},
        "gait_cycle_s": None,
        "not_available": [],
        "stages": [],
        "quality": {},
        "strength": {
            "groups": [
                {"group": g, "muscles": list(groups[g]), "factor": float(prof.factors[k]),
                 "ci_low": float(prof.ci_low[k]), "ci_high": float(prof.ci_high[k]),
                 "f_iso_generic_n": 1.0, "f_iso_n": 1.0, "status": prof.statuses()[k]}
                for k, g in enumerate(prof.group_names)
            ],
            "r2": 0.9, "r2_min": 0.5, "confidence": 0.95, "bounds": [0.5, 2.0],
            "method": "test", "joint_strength": rec,
        },
    }  # fmt: skip
    res = SessionResults({}, summary)
    figs = build_figures(res)
    assert "<svg" in figs["strength_curves"]
    html = render_html(res, figs)
    assert "Joint strength (maximal isometric moments)" in html
    assert "For ankle plantarflexion the identified curve is not determined" in html
    row = html[html.index("<td>ankle plantarflexion</td>") :].split("</tr>")[0]
    assert "<td>not determined</td>" in row and "N·m/kg" in row  # generic peak only
    row = html[html.index("<td>knee extension</td>") :].split("</tr>")[0]
    assert f"{ke['identified_peak_nm']:.0f} N·m ({ke['identified_peak_nm'] / 75:.2f}" in row
    assert "No published adult dynamometry norms" in html
    # a summary without the curves renders as before
    del summary["strength"]["joint_strength"]
    assert "Joint strength" not in render_html(SessionResults({}, summary))


def test_a_subject_model_takes_only_the_identified_groups_factors(model):
    """``StrengthProfile.applied_factors``: the identified quadriceps' 1.3 on each of its
    muscles; the soleus at its upper bound and every muscle of no group keep the generic 1;
    ``summary.strength.applied_groups`` names the quadriceps only."""
    from msk.strength.diagnosis import strength_summary

    groups = {"quads": KNEE_EXTENSORS, "soleus": ("soleus_r",)}
    prof = _profile(model, groups, [1.3, 2.0], [(1.2, 1.4), (1.8, 2.0)])
    applied = prof.applied_factors()
    assert set(applied) == {m.name for m in model.muscles}
    assert all(applied[m] == pytest.approx(1.3) for m in KNEE_EXTENSORS)
    assert applied["soleus_r"] == 1.0 and prof.strength_factors()["soleus_r"] == 2.0
    others = set(applied) - set(KNEE_EXTENSORS)
    assert all(applied[m] == 1.0 for m in others)
    strength = SimpleNamespace(profile=prof, groups=groups, protocols={}, failed={})
    assert strength_summary(strength, joint=None)["applied_groups"] == ["quads"]
