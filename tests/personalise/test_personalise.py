"""msk.personalise.personalise: the model stage's procedure as a library call with a typed
result (a synthetic walk on a known model: the markers placed where they are)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from msk.datasets.models import two_leg_model
from msk.datasets.trials import make_trial
from msk.exceptions import ConfigError
from msk.io import read_c3d
from msk.personalise import MarkerOptions, Personalisation, PersonaliseOptions, personalise
from msk.personalise.placement import CHOICE_TOLERANCE_M


@pytest.fixture(scope="module")
def walk(tmp_path_factory: pytest.TempPathFactory):
    model = two_leg_model()
    truth = make_trial(model, duration_s=1.0, rate_hz=100.0, noise_m=0.001, seed=3)
    path = truth.write_c3d(tmp_path_factory.mktemp("walk") / "walk.c3d")
    return model, read_c3d(path)


def test_personalise_from_the_motion_places_the_markers_where_they_are(walk) -> None:
    """No static, no scaling: the motion placement chosen among its candidates keeps every
    marker within 5 mm of its true offset (1 mm noise), and the typed result says what the
    summary says: the chosen candidate is the least cost within the tolerance, the task's
    markers are in the model frame with exact-zero gaps as NaN, the markers dropped on request
    only."""
    model, trial = walk
    opts = PersonaliseOptions(mass_kg=model.total_mass, height_m=1.75, side="left", scale=False)
    p = personalise(model, None, trial, opts)
    assert isinstance(p, Personalisation)
    true = {mk.name: np.asarray(mk.offset) for mk in model.markers}
    placed = {mk.name: np.asarray(mk.offset) for mk in p.model.markers}
    assert set(true) <= set(placed)
    err = max(float(np.linalg.norm(placed[k] - true[k])) for k in true)
    assert err < 0.005, err
    assert p.scaling is None and p.scale_factors == {} and "scaling" not in p.info
    choice = p.placement_choice
    assert choice is not None and p.info["placement_choice"] == choice.summary()
    costs = [c.cost_m for c in choice.candidates]
    assert choice.chosen_candidate.cost_m <= min(costs) + CHOICE_TOLERANCE_M
    assert "placement_determinacy" in p.info
    np.testing.assert_allclose(
        p.trial.markers, np.asarray(trial.markers) @ p.rotation.T, atol=1e-12
    )
    assert p.labels == trial.marker_labels and p.trial.analogs.shape[0] == 0
    slim = p.without_markers()
    assert slim.trial.markers.shape == (trial.markers.shape[0], 0, 3)
    assert slim.model is p.model and p.trial.markers.shape[1] == len(trial.marker_labels)


def test_personalise_names_an_unknown_marker_with_its_origin(walk) -> None:
    model, trial = walk
    opts = PersonaliseOptions(
        mass_kg=70.0, scale=False, origin="s.toml", markers=MarkerOptions(rename={"XX": "RASI"})
    )
    with pytest.raises(
        ConfigError, match=r"s\.toml: markers\.rename: the model has no marker 'XX'"
    ):
        personalise(model, None, trial, opts)
    bad = dataclasses.replace(opts, markers=MarkerOptions(weights={"nope": 2.0}))
    with pytest.raises(ConfigError, match=r"markers\.weights: no marker 'nope'"):
        personalise(model, None, trial, bad)
