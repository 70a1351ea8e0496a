"""A foot straddling a plate's edge (msk.dynamics.plate_footprint), on gait2392 posed in code."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from msk.dynamics.loads import Assignment, _foot_points, outside_distance
from msk.dynamics.plate_footprint import plate_edge_frames
from msk.model.files import load_model

ROOT = Path(__file__).resolve().parents[2]
UP = np.array([0.0, 1.0, 0.0])


def test_outside_distance_of_a_square() -> None:
    sq = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    d = outside_distance(np.array([[0.5, 0.5], [1.2, 0.5], [0.5, -0.3], [0.9, 0.5]]), sq)
    assert np.allclose(d, [-0.5, 0.2, 0.3, -0.1])


def _setup(toe_past_m: float):
    model = load_model(ROOT / "msk" / "data" / "models" / "gait2392.toml")
    q = np.tile(model.default_coordinates(), (5, 1))
    kin = SimpleNamespace(time=np.linspace(0.0, 0.4, 5), q=q)
    pts = _foot_points(model, q, ["calcn_r"], np.arange(5))[0][0]  # (P, 3) default pose
    low = pts[:, 1].min()
    x, z = pts[:, 0], pts[:, 2]
    front = x.max() - toe_past_m  # the plate's front edge: toe_past_m behind the toe tip
    corners = np.array([
        [x.min() - 0.1, low, z.min() - 0.1], [front, low, z.min() - 0.1],
        [front, low, z.max() + 0.1], [x.min() - 0.1, low, z.max() + 0.1],
    ])  # fmt: skip
    return model, kin, corners, pts, low


def test_toes_past_the_edge_are_not_measured() -> None:
    model, kin, corners, pts, low = _setup(0.05)
    a = [Assignment("plate1", "calcn_r", 0.0, 0.4)]
    edge, rec = plate_edge_frames(model, kin, a, {"plate1": corners}, UP,
                                  ("calcn_r", "calcn_l"))  # fmt: skip
    near = np.abs(pts[:, 1] - low) <= 0.04
    truth = float((pts[near, 0] - corners[1, 0]).max())  # the farthest ground-level point
    assert edge[:, 0].all() and not edge[:, 1].any()
    (r,) = rec
    assert r["plate"] == "plate1" and r["foot"] == "calcn_r" and r["frames"] == 5
    assert abs(r["max_outside_m"] - truth) < 1e-9 and truth > 0.04


def test_a_whole_footprint_on_the_plate_is_measured() -> None:
    model, kin, corners, _, _ = _setup(-0.02)  # the edge 2 cm beyond the toes
    a = [Assignment("plate1", "calcn_r", 0.0, 0.4)]
    edge, rec = plate_edge_frames(model, kin, a, {"plate1": corners}, UP, ("calcn_r",))
    assert not edge.any() and rec == []
    # a plate without an outline, or another foot's contact, is not judged
    edge, rec = plate_edge_frames(model, kin, a, {}, UP, ("calcn_r",))
    assert not edge.any() and rec == []
