"""Real recordings under other vendors' names (:mod:`msk.datasets.vendor_c3d`): ``msk init``
then ``msk run`` with no hand edit on each kind — Qualisys IOR/CAST, Motion Analysis Helen
Hayes with six plates, Vicon Plug-in Gait with Delsys EMG, clusters with epicondyles."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from msk.cli import main
from msk.datasets import vendor_c3d
from msk.datasets.shared import real_data_dir
from msk.io import read_c3d

pytestmark = [
    pytest.mark.realdata,
    pytest.mark.skipif(not real_data_dir().is_dir(), reason="real recordings absent"),
]

#: kind → (writer, protocol recognised, model markers recognised at least, EMG channels,
#: the event source the run uses for the right foot strike)
KINDS = {
    "qualisys": (vendor_c3d.qualisys_ior, "IOR/CAST (Van Sint Jan names)", 18, 15,
                 "file + kinematics"),
    "motion_analysis": (vendor_c3d.motion_analysis, "Helen Hayes", 9, 12, "file"),
    "vicon_delsys": (vendor_c3d.vicon_delsys, "Plug-in Gait", 8, 8, "file"),
    "clusters_epicondyles": (vendor_c3d.clusters_epicondyles, "clusters", 12, 0,
                             "file"),
}  # fmt: skip


def test_motion_analysis_copy_keeps_the_plates_and_adds_three_unloaded(tmp_path):
    s = vendor_c3d.motion_analysis(tmp_path, frames=slice(0, 60))
    src = read_c3d(real_data_dir() / "btkdata/PiG_Motion3_FF.c3d")
    got = read_c3d(s.task)
    assert len(got.plates) == 6
    n = len(got.plates[0].force)
    for a, b in zip(src.plates, got.plates[:3], strict=False):
        np.testing.assert_allclose(b.force, a.force[:n], atol=1e-6)
        np.testing.assert_allclose(b.free_moment, a.free_moment[:n], atol=1e-5)
    assert all(p.peak_force_n < 10.0 for p in got.plates[3:])
    assert "V.Sacral" in got.marker_labels and "R.Knee" in got.marker_labels
    assert {e.label for e in got.events} == {"Foot Strike", "Foot Off"}  # read as Vicon's


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(KINDS))
def test_init_then_run_with_no_hand_edit(tmp_path, kind):
    writer, protocol, n_markers, n_emg, strike_source = KINDS[kind]
    s = writer(tmp_path / "data")
    cfg = tmp_path / "session.toml"
    assert main(["init", str(s.static), str(s.task), "--out", str(cfg)]) == 0
    doc = tomllib.loads(cfg.read_text(encoding="utf-8"))
    assert {t["role"] for t in doc["trials"]} == {"static", "task"}
    # msk init recognises the static's labels (with the epicondyles), the run the task's
    init_protocol = "clusters + epicondyles" if protocol == "clusters" else protocol
    assert f"marker set: {init_protocol};" in cfg.read_text(encoding="utf-8")
    assert len(doc.get("emg", {}).get("channels", {})) == n_emg
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    ms = summary["model"]["marker_set"]
    assert ms["protocol"] == protocol  # of the task's labels (clusters: no epicondyles)
    assert len(ms["matched"]) >= n_markers
    assert summary["event_sources"]["right foot strike"] == strike_source
    assert summary["quality"]["ik_marker_rms_mean_m"] < 0.025
    # the mass from the files or weighed by the plates, agreeing with the run's own weighing
    stored = kind in ("vicon_delsys", "clusters_epicondyles")  # PROCESSING:Bodymass
    assert summary["subject"]["mass_source"] == ("config" if stored else "task_plates")
    raised = {f["quantity"] for f in summary["quality"]["flags"]}
    assert "plate_mass_difference_pct" not in raised
    assert (out / "report.html").is_file()
