from pathlib import Path

import pytest

from msk.config import TEMPLATE, load_config
from msk.exceptions import ConfigError


@pytest.fixture()
def session_dir(tmp_path: Path) -> Path:
    """The template, with the files it names created empty in a temporary tree."""
    root = tmp_path / "lab"
    (root / "pipelines").mkdir(parents=True)
    (root / "models").mkdir()
    (root / "data" / "gc5-PS").mkdir(parents=True)
    for rel in [
        "models/gait2392.toml",
        "data/gc5-PS/PS_static_for_scaling.trc",
        "data/gc5-PS/PS_ngait_og_ss1.c3d",
        "data/gc5-PS/PS_ngait_og_ss1_eTibia.csv",
    ]:
        (root / rel).write_text("")
    (root / "pipelines" / "session.toml").write_text(TEMPLATE)
    return root


def test_template_is_a_valid_config(session_dir: Path):
    cfg = load_config(session_dir / "pipelines" / "session.toml")
    assert cfg.subject.mass_kg == 75.0 and cfg.subject.side == "left"
    assert cfg.model.knee == "spline"
    assert [t.role for t in cfg.trials] == ["static", "task"]
    assert cfg.trials[1].contact_force.name == "PS_ngait_og_ss1_eTibia.csv"
    assert cfg.emg.channels["vasmed_l"] == "vasmed"
    assert cfg.trials_with_role("static")[0].name == "static"


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('side = "left"', 'side = "left"\nshoe_size = 42', "unknown key subject.shoe_size"),
        ('role = "task"', 'role = "jump"', r"trials\[1\].role = 'jump' is not one of"),
        ("mass_kg = 75.0", "mass_kg = 75000.0", "not a plausible body mass"),
        ('knee = "spline"', 'knee = "hinge"', "model.knee"),
        ("PS_ngait_og_ss1.c3d", "missing.c3d", r"trials\[1\].file: file not found: .*missing.c3d"),
        ("[filters]", "[filters]\ncutoff = 3", "unknown key filters.cutoff"),
        ("w_emg = 0.1", 'w_emg = "high"', "optimization.w_emg = 'high' should be float"),
        ('name = "gait1"', 'name = "static"', "trial names must be unique"),
    ],
)
def test_bad_configs_name_the_key_or_file(session_dir: Path, old: str, new: str, message: str):
    path = session_dir / "pipelines" / "session.toml"
    text = TEMPLATE.replace(old, new, 1)
    assert text != TEMPLATE
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_config(path)


def test_not_toml_and_missing_file(tmp_path: Path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[subject\nname=")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(bad)
    with pytest.raises(ConfigError, match="config file not found"):
        load_config(tmp_path / "nope.toml")
