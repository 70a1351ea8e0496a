"""msk.personalise.body_mass: the body mass when the configuration omits it — the C3D's subject
parameters, else the static trial's plates weighing the subject standing still."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from msk.config import load_config
from msk.exceptions import ConfigError
from msk.io.c3d import write_c3d
from msk.personalise.body_mass import G0, body_mass_from_static_plates, resolve_body_mass
from msk.trial import Subject

RATE = 100.0


def _static(mass_kg: float, *, plates: int = 2, lift_at_s: float | None = None, seed: int = 0):
    """A static trial standing still on ``plates`` plates (analog 1 kHz, the body weight split
    60/40 with 2 % N RMS noise each and a 0.3 Hz sway of the split); with ``lift_at_s`` the
    markers of one leg rise from then on (the subject steps off: not still)."""
    rng = np.random.default_rng(seed)
    t = np.arange(400) / RATE
    x = rng.uniform(-0.3, 0.3, size=(20, 3))[None] + rng.normal(0, 4e-4, (t.size, 20, 3))
    if lift_at_s is not None:
        x[t >= lift_at_s, :5, 2] += 0.5 * (t[t >= lift_at_s, None] - lift_at_s)
    ta = np.arange(4000) / 1000.0
    w = mass_kg * G0
    split = 0.6 + 0.02 * np.sin(2 * np.pi * 0.3 * ta)
    shares = {0: [], 1: [np.ones_like(ta)], 2: [split, 1 - split]}[plates]
    pl = []
    for s in shares:
        f = np.zeros((ta.size, 3))
        f[:, 2] = w * s + rng.normal(0, 2.0, ta.size)
        pl.append(SimpleNamespace(force=f, rate_hz=1000.0))
    return SimpleNamespace(
        path=Path("static.c3d"), time=t, markers=x, marker_labels=tuple(f"M{k}" for k in range(20)),
        analog_time=ta, plates=tuple(pl), up=np.array([0.0, 0.0, 1.0]), subject=Subject(),
    )  # fmt: skip


def test_static_plates_weigh_the_subject():
    m, detail = body_mass_from_static_plates(_static(68.4))
    assert m == pytest.approx(68.4, abs=0.02)
    assert "2 loaded plates" in detail and "still window" in detail


def test_one_plate_or_no_plate_does_not_weigh_the_whole_body():
    assert body_mass_from_static_plates(_static(68.4, plates=1)) is None
    assert body_mass_from_static_plates(_static(70.0, plates=0)) is None


def test_only_the_still_window_is_weighed():
    """The subject steps off (markers moving, the plates unchanged here): the window ends
    before; the mass is the standing part's."""
    tr = _static(75.0, lift_at_s=2.5)
    m, detail = body_mass_from_static_plates(tr)
    assert m == pytest.approx(75.0, abs=0.05)
    assert "0.00–2." in detail


@pytest.fixture()
def tree(tmp_path: Path) -> Path:
    (tmp_path / "model.toml").write_text("")
    for name in ("static.c3d", "walk.c3d"):
        (tmp_path / name).write_text("")
    return tmp_path


def _cfg(tree: Path, mass: str = "") -> object:
    text = (
        f'[subject]\nname = "S"\n{mass}\n[model]\nsource = "model.toml"\n\n'
        '[[trials]]\nname = "static"\nfile = "static.c3d"\nrole = "static"\n\n'
        '[[trials]]\nname = "walk"\nfile = "walk.c3d"\nrole = "task"\n'
    )
    (tree / "s.toml").write_text(text)
    return load_config(tree / "s.toml")


def test_the_configured_mass_is_used_as_given(tree: Path):
    cfg = _cfg(tree, "mass_kg = 81.0")
    out, bm = resolve_body_mass(cfg)
    assert out is cfg and bm.mass_kg == 81.0 and bm.source == "config"


def test_the_c3d_subject_parameters_then_the_static_plates(tree: Path, monkeypatch):
    x = np.random.default_rng(1).uniform(-1, 1, (20, 3, 3))
    for name, mass in (("static.c3d", None), ("walk.c3d", 71.5)):
        write_c3d(
            tree / name, markers=x, marker_labels=["A", "B", "C"], rate_hz=100.0,
            subject=Subject(mass_kg=mass),
        )  # fmt: skip
    cfg = _cfg(tree)
    assert cfg.subject.mass_kg is None
    out, bm = resolve_body_mass(cfg)
    assert out.subject.mass_kg == 71.5 and bm.source == "c3d_parameters"
    assert bm.summary() == {"mass_source": "c3d_parameters", "mass_detail": bm.detail}
    assert "walk.c3d" in bm.detail
    # no stored mass: the static's plates
    import msk.io

    monkeypatch.setattr(
        msk.io,
        "read_trial",
        lambda p: _static(64.2) if "static" in str(p) else _static(0.0, plates=0),
    )
    out, bm = resolve_body_mass(cfg)
    assert bm.source == "static_plates" and out.subject.mass_kg == pytest.approx(64.2, abs=0.02)
    # neither: a ConfigError naming the key
    monkeypatch.setattr(msk.io, "read_trial", lambda p: _static(64.2, plates=1))
    with pytest.raises(ConfigError, match=r"subject\.mass_kg"):
        resolve_body_mass(cfg)
    # an implausible weighing (a plate offset, a second person) is refused, not used
    monkeypatch.setattr(msk.io, "read_trial", lambda p: _static(8.0))
    with pytest.raises(ConfigError, match="not a plausible body mass"):
        resolve_body_mass(cfg)


@pytest.mark.slow
@pytest.mark.realdata
def test_real_statics_and_parameters(real_dir: Path):
    """gc4 JW: jw_1legstand1's plates over its double stance weigh 65.6 kg (the data set's
    stated 65.7 kg)."""
    from msk.io import read_trial

    path = real_dir / "knee-grand-challenge-gc4" / "jw_1legstand1.c3d"
    if not path.exists():
        pytest.skip("Grand Challenge data not present")
    m, _ = body_mass_from_static_plates(read_trial(path))
    assert m == pytest.approx(65.7, abs=0.3)


@pytest.mark.slow
@pytest.mark.realdata
def test_a_session_without_mass_says_where_its_mass_comes_from(tmp_path: Path, real_dir: Path):
    """gc4 JW with ``mass_kg`` removed: the run weighs the subject on the static's plates and
    its summary says so; the body weight of every ``_bw`` figure is that mass's."""
    from msk.pipeline import run_session

    repo = Path(__file__).resolve().parents[2]
    text = (repo / "pipelines" / "gc4_JW.toml").read_text(encoding="utf-8")
    if not (real_dir / "knee-grand-challenge-gc4" / "jw_1legstand1.c3d").exists():
        pytest.skip("Grand Challenge data not present")
    lines = [ln for ln in text.splitlines() if not ln.startswith("mass_kg")]
    text = "\n".join(lines).replace('"../', f'"{repo / "pipelines"}/../')
    (tmp_path / "jw.toml").write_text(text + "\n", encoding="utf-8")
    res = run_session(tmp_path / "jw.toml", tmp_path / "out")
    subj = res.summary.subject
    assert subj.mass_source == "static_plates" and "jw_1legstand1" in (subj.mass_detail or "")
    assert subj.mass_kg == pytest.approx(65.7, abs=0.3)
    assert subj.body_weight_n == pytest.approx(subj.mass_kg * G0)


def _walk(mass_kg: float, *, step_s: float = 0.55, stance_s: float = 0.66, seed: int = 0):
    """Steady walking over three plates, one whole stance each, feet alternating (step
    ``step_s``, stride 2 × step): each stance a double-hump vertical force whose impulse is
    m g × step (the stride's impulse m g T shared by its two stances), 2 N noise; the first
    and last stances of the stride pattern fall off the plates."""
    rng = np.random.default_rng(seed)
    rate = 1000.0
    ta = np.arange(int(3.0 * rate)) / rate
    pl = []
    for k in range(3):
        s0 = 0.4 + k * step_s
        u = (ta - s0) / stance_s
        inside = (u > 0) & (u < 1)
        shape = np.where(inside, np.sin(np.pi * u) + 0.25 * np.sin(3 * np.pi * u), 0.0)
        shape *= mass_kg * G0 * step_s / (shape.sum() / rate)
        f = np.zeros((ta.size, 3))
        f[:, 2] = shape + rng.normal(0, 2.0, ta.size)
        pl.append(SimpleNamespace(force=f, rate_hz=rate))
    return SimpleNamespace(path=Path("walk.c3d"), plates=tuple(pl), up=np.array([0.0, 0.0, 1.0]))


def test_task_plates_weigh_the_subject_over_a_stride():
    """Known truth: steady walking whose stances share the stride's impulse m g T; the
    estimate recovers m within 1 % with noise, for several step times; a single stance, or
    stances that do not overlap (not consecutive steps), give None."""
    from msk.personalise.body_mass import body_mass_from_task_plates

    for m_true, step in ((68.0, 0.55), (83.3, 0.6), (45.0, 0.45)):
        m, detail = body_mass_from_task_plates(_walk(m_true, step_s=step, stance_s=1.2 * step))
        assert m == pytest.approx(m_true, rel=0.01)
        assert "2 pair(s)" in detail
    one = _walk(70.0)
    one.plates = one.plates[:1]
    assert body_mass_from_task_plates(one) is None
    apart = _walk(70.0, step_s=0.8, stance_s=0.6)  # no double support between them
    assert body_mass_from_task_plates(apart) is None


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("rel", "mass_kg"),
    [("btkdata/PiG_Motion3_FF.c3d", 74.0),  # PROCESSING:Bodymass
     ("motonms-testdata/UNIPD/Walking1.c3d", 83.3),  # whole-body Newton balance (msk)
     ("knee-grand-challenge-gc4/jw_ngait_og3.c3d", 65.7)],  # single-leg stance plates
)  # fmt: skip
def test_real_walks_weigh_their_subject_within_3_percent(real_dir: Path, rel: str, mass_kg):
    from msk.io import read_trial
    from msk.personalise.body_mass import body_mass_from_task_plates

    path = real_dir / rel
    if not path.exists():
        pytest.skip(f"{rel} not present")
    m, _ = body_mass_from_task_plates(read_trial(path))
    assert m == pytest.approx(mass_kg, rel=0.03)
