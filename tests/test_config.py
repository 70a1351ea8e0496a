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
    assert cfg.emg.channels["vas_med_l"] == "vasmed"
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
        ('activation_weights = "uniform"', 'activation_weights = "mass"', "weights = 'mass'"),
        ("activation_exponent = 2.0", "activation_exponent = 1.5", "exponent = 1.5 should be"),
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


def _fes_trial(name: str, file: Path, step: str, extra: str = "") -> str:
    return (
        f'[[trials]]\nname = "{name}"\nfile = "{file.name}"\nrole = "fes"\n'
        f'fes_step = "{step}"\nstimulation_channel = "pw_us"\n{extra}\n'
    )


def test_fes_config_keys(tmp_path: Path) -> None:
    ses_files = {}
    for step in ("static", "pendulum", "dynamic", "validation"):
        ses_files[step] = tmp_path / f"{step}.csv"
        ses_files[step].write_text("time\n0\n")
    body = "".join(_fes_trial(f"fes_{s}", p, s) for s, p in ses_files.items())
    for step in ("isometric", "recruitment"):
        for k in range(3):
            p = tmp_path / f"{step}_{k}.csv"
            p.write_text("time\n0\n")
            body += _fes_trial(f"fes_{step}_{k}", p, step, "knee_angle_deg = 60.0")
    head = "[subject]\nmass_kg = 70.0\nheight_m = 1.75\n\n"
    cfg = tmp_path / "s.toml"
    cfg.write_text(head + body + "[fes]\nouter_iterations = 2\n")
    c = load_config(cfg)
    assert c.model is None  # optional in a FES-only session
    assert c.fes.outer_iterations == 2 and c.fes.fibre_fraction is None  # population prior
    fes = c.trials_with_role("fes")
    assert len(fes) == 10 and fes[0].fes is not None and fes[0].fes.step == "static"
    assert fes[0].fes.stimulation_channel == "pw_us" and fes[0].fes.angle_unit == "deg"

    cfg.write_text(head.replace("height_m = 1.75\n", "") + body)
    with pytest.raises(ConfigError, match=r"subject\.height_m is needed by the FES trials"):
        load_config(cfg)
    cfg.write_text(head + body.replace('fes_step = "validation"', 'fes_step = "dynamic"'))
    with pytest.raises(ConfigError, match="fes_step = 'validation', got 0"):
        load_config(cfg)
    cfg.write_text(head + body.replace('fes_step = "pendulum"', 'fes_step = "drop"'))
    with pytest.raises(ConfigError, match=r"trials\[1\].fes_step = 'drop' is not one of"):
        load_config(cfg)
    cfg.write_text(head + body.replace('fes_step = "static"\n', ""))
    with pytest.raises(ConfigError, match=r"missing key trials\[0\].fes_step"):
        load_config(cfg)
    cfg.write_text(head + body + "[fes]\nfibre_fraction = 1.5\n")
    with pytest.raises(ConfigError, match=r"fes\.fibre_fraction = 1\.5"):
        load_config(cfg)
    cfg.write_text(head + body + "[fes]\nfibre = 0.2\n")
    with pytest.raises(ConfigError, match=r"unknown key fes\.fibre"):
        load_config(cfg)
    # a task trial and no [model]: the model is required again
    task = tmp_path / "walk.c3d"
    task.write_text("")
    cfg.write_text(head + body + f'[[trials]]\nname = "walk"\nfile = "{task.name}"\n')
    with pytest.raises(ConfigError, match=r"missing table \[model\]: trials of role 'task'"):
        load_config(cfg)


@pytest.mark.parametrize(
    "key", ['fes_step = "static"', 'angle_unit = "deg"', "knee_angle_deg = 60.0"]
)
def test_fes_keys_only_with_role_fes(session_dir: Path, key: str):
    path = session_dir / "pipelines" / "session.toml"
    path.write_text(TEMPLATE.replace('role = "task"', f'role = "task"\n{key}', 1))
    name = key.split(" ")[0]
    with pytest.raises(ConfigError, match=rf"trials\[1\]\.{name} is only valid with role = 'fes'"):
        load_config(path)


def test_template_fes_example_parses(session_dir: Path):
    """The commented FES example of the template, uncommented, parses (alone
    it is not a protocol)."""
    lines = TEMPLATE.splitlines()
    start = lines.index("# [[trials]]")
    fes = [ln[2:] if ln.startswith("# ") else ln for ln in lines[start:]]
    (session_dir / "data" / "fes").mkdir()
    (session_dir / "data" / "fes" / "pendulum.csv").write_text("time\n0\n")
    text = "\n".join(lines[:start] + fes) + "\n"
    path = session_dir / "pipelines" / "session.toml"
    path.write_text(text)
    # one FES trial is not a protocol: the missing steps are named
    with pytest.raises(ConfigError, match="needs at least 1 trial\\(s\\) with fes_step = 'static'"):
        load_config(path)


def test_grf_and_marker_move_keys(session_dir: Path):
    """``grf`` (an OpenSim GRF file for a task trial, needed by a .trc task) and
    ``markers.move`` (a list of model markers; needs a static trial)."""
    path = session_dir / "pipelines" / "session.toml"
    data = session_dir / "data" / "gc5-PS"
    (data / "walk.trc").write_text("")
    (data / "walk_grf.mot").write_text("")
    trc_task = TEMPLATE.replace("PS_ngait_og_ss1.c3d", "walk.trc", 1)
    with_grf = trc_task.replace(
        'role = "task"\n', 'role = "task"\ngrf = "../data/gc5-PS/walk_grf.mot"\n', 1
    ).replace("move = []", 'move = ["R.Thigh.Upper"]', 1)
    path.write_text(with_grf)
    cfg = load_config(path)
    assert cfg.trials[1].grf == (data / "walk_grf.mot").resolve()
    assert cfg.trials[0].grf is None and cfg.marker_move == ("R.Thigh.Upper",)
    for text, message in (
        (trc_task, r"trials\[1\].file is a .trc .*trials\[1\].grf"),
        (
            TEMPLATE.replace('role = "static"\n', 'role = "static"\ngrf = "x.mot"\n', 1),
            r"trials\[0\].grf: file not found",
        ),
        (
            TEMPLATE.replace(
                'role = "static"\n', 'role = "static"\ngrf = "../data/gc5-PS/walk_grf.mot"\n', 1
            ),
            r"trials\[0\].grf is only valid with role = 'task'",
        ),
        (
            TEMPLATE.replace(
                'role = "task"\n', 'role = "task"\ngrf = "../data/gc5-PS/walk_grf.mot"\n', 1
            ),
            r"trials\[1\].grf goes with a .trc trial file .* PS_ngait_og_ss1.c3d",
        ),
        (TEMPLATE.replace("move = []", "move = [3]", 1), "markers.move = .* list of marker"),
        (
            TEMPLATE.replace('name = "gait1"', 'name = "../../x"', 1),
            r"trials\[1\].name = '../../x' must be a plain name",
        ),
        (
            TEMPLATE.replace("# intercondylar_distance_m = 0.04", "intercondylar_distance_m = 4.0"),
            r"contact.intercondylar_distance_m = 4.0 m is outside \[0.01, 0.1\] m \(adult knees",
        ),
    ):
        path.write_text(text)
        with pytest.raises(ConfigError, match=message):
            load_config(path)


# --- issue 18: special files, encodings, number ranges with units -----------------------------
@pytest.mark.parametrize("special", ["fifo", "/dev/zero", "dir"])
def test_special_files_are_refused_without_hanging(session_dir: Path, special: str):
    import os

    path = session_dir / "pipelines" / "session.toml"
    if special == "fifo":
        target = session_dir / "data" / "pipe.c3d"
        os.mkfifo(target)
    elif special == "dir":
        target = session_dir / "data"
    else:
        target = Path(special)
    path.write_text(TEMPLATE.replace("../data/gc5-PS/PS_ngait_og_ss1.c3d", str(target)))
    with pytest.raises(ConfigError, match=r"trials\[1\]\.file: .* not a regular file"):
        load_config(path)
    if special == "fifo":
        with pytest.raises(ConfigError, match="FIFO"):
            load_config(target)


def test_non_utf8_config_is_one_line(session_dir: Path):
    path = session_dir / "pipelines" / "session.toml"
    latin1 = TEMPLATE.encode("utf-8").replace(b'"PS"', b'"M\xfcller"')  # Latin-1 u-umlaut
    path.write_bytes(latin1)
    with pytest.raises(ConfigError, match="not UTF-8") as exc:
        load_config(path)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "kinematics_cutoff_hz = 6.0",
            "kinematics_cutoff_hz = 0",
            r"= 0.0 Hz is outside \[0.01, 500\] Hz",
        ),
        ("kinematics_cutoff_hz = 6.0", "kinematics_cutoff_hz = 1e-9", "1e-09 Hz is outside"),
        ("kinematics_cutoff_hz = 6.0", "kinematics_cutoff_hz = nan", "nan Hz is outside"),
        ("grf_cutoff_hz = 6.0", "grf_cutoff_hz = inf", r"grf_cutoff_hz = inf Hz"),
        (
            "lowpass_hz = 6.0",
            "lowpass_hz = -6.0",
            r"emg.lowpass_hz = -6.0 Hz is outside \(0, 500\]",
        ),
        (
            "electromechanical_delay_s = 0.04",
            "electromechanical_delay_s = 40",
            r"= 40.0 s is outside \[0, 0.2\] s \(milliseconds typed as seconds\? 40 ms is 0.04 s\)",
        ),
        (
            "weights = {}",
            'weights = { RASI = "high" }',
            r"markers.weights.RASI = 'high' should be a finite",
        ),
        ("weights = {}", "weights = { RASI = nan }", "markers.weights.RASI = nan"),
        ("weights = {}", "weights = { RASI = -1 }", "markers.weights.RASI = -1"),
        ("rename = {}", "rename = { RASI = 3 }", "markers.rename.RASI = 3 should be"),
        (
            "mass_kg = 75.0",
            "mass_kg = 10.0",
            r"subject.mass_kg = 10.0 kg is outside \[20, 300\] kg",
        ),
        ("height_m = 1.70", "height_m = 1700", r"1700.0 m is outside .*1.68 m"),
        ('solver = "daqp"', 'solver = "dapq"', "optimization.solver = 'dapq' is not one of"),
        ("w_emg = 0.1", "w_emg = nan", "optimization.w_emg = nan"),
        ('vas_med_l = "vasmed"', "vas_med_l = 1", "emg.channels.vas_med_l = 1 should be"),
    ],
)
def test_numbers_are_range_checked_with_their_unit(session_dir, old, new, message):
    path = session_dir / "pipelines" / "session.toml"
    text = TEMPLATE.replace(old, new, 1)
    assert text != TEMPLATE
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as exc:
        load_config(path)
    assert "\n" not in str(exc.value)


def test_emg_mvc_values(tmp_path):
    """``[emg] mvc``: positive numbers for channels the mapping uses, else one clear line."""
    path = tmp_path / "lab" / "pipelines" / "session.toml"
    path.parent.mkdir(parents=True)
    root = tmp_path / "lab"
    (root / "models").mkdir()
    (root / "models" / "gait2392.toml").write_text("")
    (root / "data" / "gc5-PS").mkdir(parents=True)
    for f in ("PS_static_for_scaling.trc", "PS_ngait_og_ss1.c3d", "PS_ngait_og_ss1_eTibia.csv"):
        (root / "data" / "gc5-PS" / f).write_text("")
    ok = TEMPLATE.replace("# mvc = { vasmed = 0.31, vaslat = 0.29 }", "mvc = { vasmed = 0.31 }")
    path.write_text(ok)
    assert load_config(path).emg.mvc == {"vasmed": 0.31}
    for text, message in (
        (ok.replace("vasmed = 0.31 }", "vasmed = -1.0 }"), "emg.mvc.vasmed = -1.0 should be"),
        (ok.replace("{ vasmed = 0.31 }", "{ soleus = 0.2 }"), "names channel 'soleus'"),
    ):
        path.write_text(text)
        with pytest.raises(ConfigError, match=message):
            load_config(path)


def test_grf_cutoff_defaults_to_the_kinematics_cutoff(session_dir: Path):
    """Absent ``grf_cutoff_hz``: the plates are low-passed at the kinematics' cut-off (one
    filter on both, Kristianslund et al. 2012); given, it is used as given."""

    path = session_dir / "pipelines" / "session.toml"
    text = TEMPLATE.replace("kinematics_cutoff_hz = 6.0", "kinematics_cutoff_hz = 8.0")
    path.write_text("\n".join(ln for ln in text.splitlines() if "grf_cutoff_hz" not in ln))
    cfg = load_config(path)
    assert cfg.filters.grf_cutoff_hz is None and cfg.filters.grf_cutoff_used_hz == 8.0
    path.write_text(text.replace("grf_cutoff_hz = 6.0", "grf_cutoff_hz = 15.0"))
    assert load_config(path).filters.grf_cutoff_used_hz == 15.0
