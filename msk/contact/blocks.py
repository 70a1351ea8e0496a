"""Knee contact of a whole trial assembled block by block of frames: the contact force
(:func:`msk.contact.knee.knee_contact_force`) and its two-point medial/lateral split
(:func:`msk.contact.knee.split_medial_lateral`; Winby et al. 2009, Lerner et al. 2015) filled
into trial-long arrays one block of frames at a time, so that neither the muscle forces nor the
knee's unit wrenches ∂l/∂ξ of the whole trial are ever held at once.

Every frame is independent in both formulas (the distal Newton–Euler balance and the
muscles' pull ``Σ_i F_i ∂l_i/∂ξ`` of one frame use that frame only), so the blocks' union is
the one-pass result to round-off whatever the blocks are."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from msk.contact.knee import PlateauGeometry, knee_contact_force, split_medial_lateral
from msk.contact.patella import PatellarTendon
from msk.dynamics.loads import ExternalLoads
from msk.kinematics.ik import Kinematics
from msk.model.core import Model

__all__ = ["ContactAssembly", "ContactVariant"]


@dataclass(frozen=True)
class ContactVariant:
    """One model's knee contact force (N, 3) in the knee joint frame fixed in the tibia, its
    magnitude and medial/lateral compartment forces (N); NaN where there is no muscle force.

    By component (:mod:`msk.contact.knee`'s plateau frame: x anterior, y proximal along the
    tibia's long axis — the plateau normal —, z to the subject's right; ``force`` is the femur's
    on the tibia): :attr:`axial` = −F_y (compressive positive), :attr:`shear_anterior` = F_x
    (on the tibia, anterior positive), :attr:`shear_lateral` = ``lateral_sign`` · F_z (toward
    the knee's lateral side: +1 on a right knee, −1 on a left one)."""

    force: np.ndarray
    total: np.ndarray
    medial: np.ndarray
    lateral: np.ndarray
    lateral_sign: float = 1.0
    #: (N,) the patellofemoral contact force |F_PF| in N with the patellar tendon
    #: (:meth:`msk.contact.patella.PatellarTendon.patellofemoral`), else None
    patellofemoral: np.ndarray | None = None

    @property
    def axial(self) -> np.ndarray:
        """(N,) compressive force along the tibia's long axis (plateau normal), N."""
        return -np.asarray(self.force)[:, 1]

    @property
    def shear_anterior(self) -> np.ndarray:
        """(N,) anterior–posterior shear on the tibia (anterior positive), N."""
        return np.asarray(self.force)[:, 0]

    @property
    def shear_lateral(self) -> np.ndarray:
        """(N,) medial–lateral shear on the tibia (lateral positive), N."""
        return self.lateral_sign * np.asarray(self.force)[:, 2]

    def component(self, name: str) -> np.ndarray:
        """(N,) the predicted force a measurement of ``name`` measures: ``"axial"`` →
        :attr:`axial`, ``"magnitude"`` / ``"unstated"`` → :attr:`total` (N)."""
        return self.axial if name == "axial" else self.total


class ContactAssembly:
    """One model's knee contact force and medial/lateral split on every frame of a trial (NaN
    until filled), filled block by block of frames by :meth:`fill`; :meth:`result` gives the
    :class:`ContactVariant`.

    Args:
        model: the model whose inertias and muscles the contact uses.
        geometry: the two contact points of the split (:func:`msk.contact.knee.plateau_geometry`).
        kinematics: the whole trial's kinematics (its ``time`` sets the frame count).
        external: the whole trial's external loads on the same time, or ``None``.
        joint: the knee joint (``knee_r`` / ``knee_l``; a left knee's lateral side is −z).
        patella: the patellar tendon the quadriceps act through
            (:func:`msk.contact.patella.patellar_tendon`), or ``None``: along their own paths.
    """

    def __init__(
        self,
        model: Model,
        geometry: PlateauGeometry,
        kinematics: Kinematics,
        external: ExternalLoads | None,
        joint: str,
        patella: PatellarTendon | None = None,
    ) -> None:
        n = int(np.asarray(kinematics.time).size)
        self.model, self.geometry, self.kinematics = model, geometry, kinematics
        self.external, self.joint, self.patella = external, joint, patella
        self.force: NDArray[np.float64] = np.full((n, 3), np.nan)
        self.medial: NDArray[np.float64] = np.full(n, np.nan)
        self.lateral: NDArray[np.float64] = np.full(n, np.nan)
        self.patellofemoral: NDArray[np.float64] | None = (
            None if patella is None else np.full(n, np.nan)
        )

    def fill(
        self,
        frames: ArrayLike,
        forces: ArrayLike,
        distal_wrenches: ArrayLike,
        muscle_names: Sequence[str],
        knee_jacobian: ArrayLike | None = None,
    ) -> None:
        """The contact on ``frames`` (indices into the trial) with these muscle ``forces``
        (frames, muscles; columns ``muscle_names``) and the knee's unit wrenches
        ``distal_wrenches`` (frames, muscles, 6) of those frames; with a patella, the muscles'
        length Jacobian on the knee coordinate ``knee_jacobian`` (frames, muscles).

        Only the frames where every muscle with a wrench on the knee's distal side has a force
        are filled: a muscle without one (NaN: the other leg, left out of the muscle-force
        solve where its foot stands off the plates) does not load this knee and counts as 0.
        """
        fr = np.asarray(frames, dtype=np.intp).reshape(-1)
        f = np.asarray(forces, dtype=float)
        w = np.asarray(distal_wrenches, dtype=float)
        loads_knee = (w != 0).any(axis=2)
        known = np.isfinite(f)
        keep = (known | ~loads_knee).all(axis=1)
        fr, f, w = fr[keep], np.where(known, f, 0.0)[keep], w[keep]
        jk = None if knee_jacobian is None else np.asarray(knee_jacobian, dtype=float)[keep]
        if not fr.size:
            return
        contact = knee_contact_force(
            self.model, self.kinematics.take(fr),
            None if self.external is None else self.external.take(fr),
            muscle_forces=f, muscle_names=tuple(muscle_names), joint=self.joint,
            distal_wrenches=w, patella=self.patella,
            knee_jacobian=jk if self.patella is not None else None,
        )  # fmt: skip
        self.force[fr] = contact.force
        if self.patellofemoral is not None and contact.patellofemoral is not None:
            self.patellofemoral[fr] = contact.patellofemoral
        ml = split_medial_lateral(contact, self.geometry)
        self.medial[fr], self.lateral[fr] = ml.medial, ml.lateral

    def result(self) -> ContactVariant:
        """The trial's :class:`ContactVariant` (NaN on frames never filled)."""
        return ContactVariant(
            self.force, np.linalg.norm(self.force, axis=1), self.medial, self.lateral,
            lateral_sign=-1.0 if self.joint.endswith("_l") else 1.0,
            patellofemoral=self.patellofemoral,
        )  # fmt: skip
