"""TOML model files: exact round trip, the shipped models, bad files."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msk.datasets.models import leg_model
from msk.datasets.shared import REPO_ROOT
from msk.exceptions import FileFormatError, ModelError
from msk.model.core import marker_positions
from msk.model.files import function_from_dict, function_to_dict, load_model, save_model
from msk.model.joints import (
    Composite,
    Constant,
    FourBarKnee,
    FourBarTranslation,
    Linear,
    Multiplier,
    PiecewiseLinear,
    Polynomial,
    SimmSpline,
)
from msk.model.osim import load_osim
from msk.muscles.path import MovingPathPoint

MODELS = REPO_ROOT / "msk" / "data" / "models"


def _same_model(a, b, rng):
    assert a.name == b.name and a.coordinate_names == b.coordinate_names
    np.testing.assert_array_equal(a.gravity, b.gravity)
    for x, y in zip(a.bodies, b.bodies):
        assert x.name == y.name and x.mass == y.mass
        np.testing.assert_array_equal(x.com, y.com)
        np.testing.assert_array_equal(x.inertia, y.inertia)
    for x, y in zip(a.coordinates, b.coordinates):
        assert x == y
    lo, hi = a.coordinate_bounds()
    th = rng.uniform(np.maximum(lo, -1.0), np.minimum(hi, 1.0), size=(5, a.n_coords))
    if a.markers:
        np.testing.assert_array_equal(marker_positions(a, th), marker_positions(b, th))
    np.testing.assert_array_equal(a.coupling.q(th), b.coupling.q(th))
    np.testing.assert_array_equal(a.coupling.jacobian(th), b.coupling.jacobian(th))
    da, db = a.create_data(), b.create_data()
    for t in th:
        q = a.coupling.q(t)
        pin.framesForwardKinematics(a.pin_model, da, q)
        pin.framesForwardKinematics(b.pin_model, db, q)
        for name in a.body_frame:
            np.testing.assert_array_equal(
                da.oMf[a.body_frame[name]].homogeneous, db.oMf[b.body_frame[name]].homogeneous
            )
    assert len(a.muscles) == len(b.muscles)
    for m, n in zip(a.muscles, b.muscles):
        assert (m.name, m.kind, m.max_isometric_force, m.optimal_fiber_length) == (
            n.name,
            n.kind,
            n.max_isometric_force,
            n.optimal_fiber_length,
        )
        assert (m.tendon_slack_length, m.pennation_angle) == (
            n.tendon_slack_length,
            n.pennation_angle,
        )
        assert m.extra == n.extra
        assert [type(p) for p in m.points] == [type(p) for p in n.points]
        for p, r in zip(m.points, n.points):
            np.testing.assert_array_equal(p.location, r.location)
            if isinstance(p, MovingPathPoint):
                assert p.coordinates == r.coordinates
        assert [(w.wrap_object, w.method, w.range) for w in m.wraps] == [
            (w.wrap_object, w.method, w.range) for w in n.wraps
        ]


@pytest.mark.parametrize(
    "rel", ["opensim-models/gait2392_thelen2003muscle.osim", "opensim-models/Rajagopal2016.osim"]
)
def test_round_trip_of_imported_models_is_exact(ref_dir, tmp_path, rel):
    model = load_osim(ref_dir / rel)
    back = load_model(save_model(model, tmp_path / "m.toml", header="test\nheader"))
    _same_model(model, back, np.random.default_rng(0))
    assert len(back.metadata.get("wrap_objects", ())) == len(model.metadata.get("wrap_objects", ()))
    assert (tmp_path / "m.toml").read_text().startswith("# test\n# header\n")


def test_round_trip_of_code_built_model_with_four_bar(tmp_path):
    knee = FourBarKnee((-0.01, -0.395), (0.008, -0.4), (0.012, -0.01), (-0.018, -0.022))
    model = leg_model(FourBarTranslation(knee, 0), FourBarTranslation(knee, 1))
    back = load_model(save_model(model, tmp_path / "leg.toml"))
    _same_model(model, back, np.random.default_rng(1))


def test_shipped_models_load_and_match_their_source(ref_dir):
    spline = load_model(MODELS / "gait2392.toml")
    four = load_model(MODELS / "gait2392_fourbar.toml")
    osim = load_osim(ref_dir / "opensim-models/gait2392_thelen2003muscle.osim")
    for m in (spline, four):
        assert len(m.muscles) == 92 and len(m.markers) == 39 and m.n_coords == 23
        assert m.total_mass == pytest.approx(osim.total_mass, rel=1e-15)
        assert m.root_joint == "ground_pelvis"
    th = np.zeros((1, 23))
    np.testing.assert_array_equal(spline.coupling.q(th), osim.coupling.q(th))
    knee = next(j for j in four.joints if j.name == "knee_r")
    assert isinstance(knee.axes[0].function, FourBarTranslation)
    # the four-bar knee keeps the tibia within 1 mm of the spline knee over 0–120°
    k = four.coordinate_index("knee_angle_r")
    th = np.zeros((121, 23))
    th[:, k] = np.linspace(0.0, -2.094, 121)
    d = np.linalg.norm(spline.coupling.q(th)[:, 9:11] - four.coupling.q(th)[:, 9:11], axis=1)
    assert np.sqrt(np.mean(d**2)) < 1e-3


def test_the_shipped_rajagopal_model_matches_its_source(ref_dir):
    """``source = "rajagopal"``: the Apache-2.0 Rajagopal-derived model of opensim-core's
    example3DWalking, read by name, the same numbers as its .osim."""
    from msk.model.files import model_file

    assert model_file("rajagopal") == (MODELS / "rajagopal.toml").resolve()
    shipped = load_model("rajagopal")
    osim = load_osim(ref_dir / "opensim-core/subject_walk_scaled.osim")
    assert len(shipped.muscles) == len(osim.muscles) == 80
    assert shipped.marker_names == osim.marker_names
    assert shipped.coordinate_names == osim.coordinate_names
    assert shipped.total_mass == pytest.approx(osim.total_mass, rel=1e-15)
    assert "Apache" in shipped.metadata["licence"]
    th = np.random.default_rng(2).uniform(-0.3, 0.3, (5, shipped.n_coords))
    np.testing.assert_allclose(shipped.coupling.q(th), osim.coupling.q(th), atol=1e-12)


_FUNCS = st.sampled_from(
    [
        Constant(0.3),
        Linear(-1.5, 0.25),
        Polynomial((0.1, -0.2, 0.3, 1e-7)),
        SimmSpline((0.0, 0.5, 1.5, 2.0), (0.1, 0.2, -0.3, 0.05)),
        PiecewiseLinear((0.0, 1.0, 2.0), (1.0, -1.0, 0.5)),
        Multiplier(SimmSpline((0.0, 1.0, 2.0), (0.0, 1.0, 0.0)), 1.1472),
        Composite(Polynomial((1.0, 0.0, 0.0)), Linear(0.5, 0.1)),
        FourBarTranslation(
            FourBarKnee((-0.01, -0.395), (0.008, -0.4), (0.012, -0.01), (-0.018, -0.022)), 1
        ),
    ]
)


@settings(max_examples=40, deadline=None)
@given(_FUNCS, st.floats(-1.5, 0.0))
def test_function_dicts_round_trip(f, x):
    g = function_from_dict(function_to_dict(f))
    assert g(x) == f(x)
    assert g.d1(x) == f.d1(x)


def test_bad_files_raise_typed_errors(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[model\nname=1")
    with pytest.raises(FileFormatError, match="invalid TOML"):
        load_model(p)
    p.write_text('[model]\nname = "x"\n')
    with pytest.raises(FileFormatError, match="not an msk model"):
        load_model(p)
    p.write_text(
        '[model]\nformat = "msk-model"\nname = "x"\n[[bodies]]\nname = "b"\nmass = 1.0\n'
        "com = [0.0, 0.0]\ninertia = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]\n"
    )
    with pytest.raises(FileFormatError, match=r"body b: com must have shape \(3,\)"):
        load_model(p)
    p.write_text(
        '[model]\nformat = "msk-model"\nname = "x"\n[[joints]]\nname = "j"\nparent = "ground"\n'
        'child = "nobody"\n'
    )
    with pytest.raises(ModelError, match="unknown child body 'nobody'"):
        load_model(p)
    with pytest.raises(FileFormatError, match="unknown function type 'Sine'"):
        function_from_dict({"type": "Sine"}, "here")


def test_scaled_four_bar_model_round_trips(tmp_path):
    from msk.personalise.scaling import apply_scale_factors

    model = apply_scale_factors(
        load_model(MODELS / "gait2392_fourbar.toml"),
        {"femur_r": [1.1, 1.05, 1.0], "tibia_r": 0.95},
        body_mass=80.0,
    )
    knee = next(j for j in model.joints if j.name == "knee_r")
    assert isinstance(knee.axes[0].function, Multiplier)
    back = load_model(save_model(model, tmp_path / "scaled.toml"))
    _same_model(model, back, np.random.default_rng(3))
    assert back.metadata["scale_factors"]["femur_r"] == [1.1, 1.05, 1.0]


# ------------------------------------------------------------------------------------------
# shipped models by name
# ------------------------------------------------------------------------------------------


def test_a_bare_name_is_a_shipped_model(tmp_path) -> None:
    from msk.config import load_config
    from msk.model.files import model_file, shipped_models

    assert {"gait2392", "gait2392_fourbar"} <= set(shipped_models())
    path = model_file("gait2392")
    assert path == (MODELS / "gait2392.toml").resolve() and path.is_file()
    assert load_model("gait2392").marker_names == load_model(MODELS / "gait2392.toml").marker_names
    # a path stays a path (relative to the base folder)
    assert model_file("m.toml", base=tmp_path) == tmp_path / "m.toml"
    # a session names the model by name, from a folder holding no model
    (tmp_path / "t.c3d").write_text("")
    cfg = tmp_path / "s.toml"
    cfg.write_text(
        '[subject]\nname = "x"\nmass_kg = 70.0\nheight_m = 1.7\n'
        '[model]\nsource = "gait2392"\nknee = "four_bar"\n'
        '[[trials]]\nname = "w"\nfile = "t.c3d"\nrole = "task"\n'
    )
    from msk.pipeline.inputs import model_source

    assert model_source(load_config(cfg)) == (MODELS / "gait2392_fourbar.toml").resolve()


def test_a_misspelt_model_name_is_a_config_error_with_a_suggestion(tmp_path) -> None:
    from msk.config import load_config
    from msk.exceptions import ConfigError
    from msk.model.files import model_file

    with pytest.raises(ModelError, match=r"shipped: gait2392.*did you mean 'gait2392'"):
        model_file("gait2329")
    (tmp_path / "t.c3d").write_text("")
    cfg = tmp_path / "s.toml"
    cfg.write_text(
        '[subject]\nname = "x"\nmass_kg = 70.0\nheight_m = 1.7\n[model]\nsource = "gait_2392"\n'
        '[[trials]]\nname = "w"\nfile = "t.c3d"\nrole = "task"\n'
    )
    with pytest.raises(ConfigError, match=r"model\.source = 'gait_2392'.*did you mean 'gait2392'"):
        load_config(cfg)


@pytest.mark.slow
def test_the_wheel_ships_the_models(tmp_path) -> None:
    """A non-editable install holds the models: the wheel built from the tree lists them, and
    installed (no editable link to the tree) it reads gait2392 by name from another folder."""
    import subprocess
    import sys
    import zipfile

    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path),
         str(REPO_ROOT)],
        check=True, capture_output=True, timeout=600,
    )  # fmt: skip
    (wheel,) = tmp_path.glob("msk-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for model in ("gait2392", "gait2392_fourbar", "rajagopal"):
        assert f"msk/data/models/{model}.toml" in names
    site = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site),
         str(wheel)],
        check=True, capture_output=True, timeout=600,
    )  # fmt: skip
    code = (
        "import msk.model.files as f; print(f.__file__, len(f.load_model('gait2392').muscles), "
        "len(f.load_model('rajagopal').muscles))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env={"PYTHONPATH": str(site)},
        check=True, capture_output=True, text=True, timeout=600,
    ).stdout.split()  # fmt: skip
    assert out[0].startswith(str(site)) and int(out[1]) == 92 and int(out[2]) == 80


def model_names_markdown(name: str) -> str:
    """The user guide's list of a shipped model's marker names (by body) and muscle names."""
    model = load_model(name)
    bodies: dict[str, list[str]] = {}
    for mk in model.markers:
        bodies.setdefault(mk.body, []).append(mk.name)
    lines = [
        f"Markers of `{name}` (the keys of `[markers] rename`, `weights` and `move`), by body:",
        "",
        "| body | markers |",
        "| --- | --- |",
        *(f"| `{b}` | {', '.join(f'`{m}`' for m in ms)} |" for b, ms in bodies.items()),
        "",
    ]
    muscles = [m.name for m in model.muscles]
    right = [m for m in muscles if m.endswith("_r")]
    paired = all(f"{m[:-2]}_l" in muscles for m in right)
    others = [m for m in muscles if not m.endswith(("_r", "_l"))]
    lines += [
        f"Muscles of `{name}` (the keys of `[emg] channels`): {len(muscles)}, the right side's "
        + ("below; each has a left twin ending `_l`:" if paired else "below:"),
        "",
        ", ".join(f"`{m}`" for m in right),
    ]
    if others:
        lines += ["", "Unsided: " + ", ".join(f"`{m}`" for m in others)]
    return "\n".join(lines) + "\n"


def test_the_user_guide_lists_the_names_of_gait2392() -> None:
    import os
    import re

    guide = REPO_ROOT / "docs" / "user-guide.md"
    text = guide.read_text(encoding="utf-8")
    block = re.compile(r"(rewrites this section \(a test checks it matches the model\) -->\n\n)"
                       r"(.*?)(<!-- end of the generated names -->)", re.S)  # fmt: skip
    names = model_names_markdown("gait2392")
    if os.environ.get("MSK_UPDATE_DOCS") == "1":
        text = block.sub(lambda m: m.group(1) + names + "\n" + m.group(3), text)
        guide.write_text(text, encoding="utf-8")
    found = block.search(text)
    assert found is not None, "docs/user-guide.md: the generated section's markers are missing"
    assert found.group(2) == names + "\n", "docs/user-guide.md: MSK_UPDATE_DOCS=1 rewrites it"
