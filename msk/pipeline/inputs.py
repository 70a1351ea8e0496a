"""What every stage may read: the session configuration resolved once (files, hashes, roles).

:func:`session_inputs` turns a :class:`~msk.config.SessionConfig` into a frozen
:class:`SessionInputs`; stages receive it as their first argument and never change it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from msk.config import ModelConfig, SessionConfig, TrialConfig
from msk.exceptions import ConfigError
from msk.pipeline.runner import file_sha256
from msk.units import G0

__all__ = ["G0", "SessionInputs", "plain_settings", "session_inputs"]


@dataclass(frozen=True)
class SessionInputs:
    """One session's configuration and input files.

    ``task``/``static``/``model_source``/``model_cfg`` are ``None`` in a pure FES session
    (``gait`` False); ``files`` maps a role (``task``, ``static``, ``grf``, ``model``,
    ``fes:<name>``…) to its path and ``hashes`` to its sha256; ``inv_rename`` maps lab labels
    to model marker names (``[markers] rename``)."""

    cfg: SessionConfig
    gait: bool
    task: TrialConfig | None
    static: TrialConfig | None
    mass_trials: tuple[TrialConfig, ...]
    mvc_trials: tuple[TrialConfig, ...]
    fes_trials: tuple[TrialConfig, ...]
    model_source: Path | None
    model_cfg: ModelConfig | None
    files: Mapping[str, Path]
    hashes: Mapping[str, str]
    inv_rename: Mapping[str, str]
    #: where ``cfg.subject.mass_kg`` comes from (:mod:`msk.personalise.body_mass`): ``mass_source``
    #: (``config``, ``c3d_parameters``, ``static_plates``, ``task_plates``) and ``mass_detail``
    mass: Mapping[str, str] = field(default_factory=dict)

    @property
    def mass_kg(self) -> float:
        """The body mass (kg): the configuration's, else the one :func:`session_inputs`
        found in the trial files (never None here)."""
        if self.cfg.subject.mass_kg is None:
            raise ConfigError(f"{self.cfg.path}: no body mass (subject.mass_kg)")
        return float(self.cfg.subject.mass_kg)

    @property
    def inertias_by_status(self) -> bool:
        """``[model] inertias = "by_status"``: the dynamics downstream of the mass
        identification apply only the segments it identified
        (:func:`msk.dynamics.identification.identified_model`)."""
        return self.cfg.model is not None and self.cfg.model.inertias == "by_status"

    @property
    def side(self) -> str:
        """``left`` or ``right``: the leg whose muscles and knee are analysed."""
        return self.cfg.subject.side

    @property
    def sfx(self) -> str:
        """Coordinate/body suffix of the analysed side (``_r`` or ``_l``)."""
        return "_l" if self.side == "left" else "_r"

    @property
    def body_weight(self) -> float:
        """Body mass (:attr:`mass_kg`) × standard gravity (N)."""
        return self.mass_kg * G0

    def labels_of(self, labels: tuple[str, ...] | list[str]) -> tuple[str, ...]:
        """Lab marker labels in model names (``[markers] rename``)."""
        return tuple(self.inv_rename.get(lab, lab) for lab in labels)

    def external_loads(
        self,
        model: Any,
        trial: Any,
        kinematics: Any,
        plates: Any = None,
        assignment: Mapping[str, str] | None = None,
    ) -> Any:
        """:func:`msk.dynamics.loads.external_loads` of a trial: its plates (a C3D's, or
        ``plates``), with the explicit assignment of the ExternalLoads ``.xml`` then of the
        config's ``[loads] assign``, low-passed at ``[filters]``' ground-reaction cut-off."""
        from msk.dynamics.loads import external_loads, plates_from_trial

        plates = plates_from_trial(trial) if plates is None else plates
        assign = {**(assignment or {}), **self.cfg.loads.assign} or None
        return external_loads(
            model, kinematics, plates, assignment=assign,
            cutoff_hz=self.cfg.filters.grf_cutoff_used_hz,
            surface_heights=dict(self.cfg.loads.surface_height_m),
        )  # fmt: skip

    def knee_plateau(self, model: Any, joint: str) -> Any:
        """The two contact points of ``joint`` as ``[contact]`` places them
        (:func:`msk.contact.knee.plateau_geometry`): the same for the compartment rows of the
        muscle forces and the knee contact's split."""
        from msk.contact.knee import plateau_geometry

        cc = self.cfg.contact
        centre = None if cc.plateau_depth_m is None else (0.0, -cc.plateau_depth_m, 0.0)
        return plateau_geometry(
            model, joint=joint, intercondylar_distance_m=cc.intercondylar_distance_m,
            centre_m=centre,
        )  # fmt: skip

    def muscle_force_options(self, model: Any) -> dict[str, Any]:
        """The keyword arguments of :func:`msk.optimization.muscle_forces.solve_muscle_forces`
        this session's configuration sets for ``model``: ``[optimization]``, the EMG channels
        (the groups of ``emg_assisted``'s gains) and the side's knee with its contact points
        (the compartment rows of ``compartment_nonnegative``)."""
        from msk.contact.patella import patella_mode
        from msk.model.conventions import knee_joint

        found = knee_joint(model, self.sfx)
        joint = found if found is not None else f"knee{self.sfx}"
        plateau = None
        if self.cfg.optimization.compartment_nonnegative and found is not None:
            plateau = self.knee_plateau(model, joint)
        return {
            "options": self.cfg.optimization,
            "emg_channels": self.cfg.emg.channels,
            "knee_joint": joint,
            "knee_plateau": plateau,
            "knee_patella": patella_mode(model, joint, self.cfg.contact.patella) == "tendon",
        }


def model_source(cfg: SessionConfig) -> Path:
    """The model file of ``[model]``; with ``knee = "four_bar"`` its ``_fourbar`` twin."""
    if cfg.model is None:  # load_config requires [model] with a gait trial
        raise ConfigError(f"{cfg.path}: a gait trial (role 'task') needs a [model] table")
    src = cfg.model.source
    if cfg.model.knee == "four_bar" and "fourbar" not in src.stem:
        alt = src.with_name(f"{src.stem}_fourbar{src.suffix}")
        if not alt.is_file():
            raise ConfigError(
                f"{cfg.path}: model.knee = 'four_bar' but {src.name} has a spline knee and "
                f"{alt.name} does not exist"
            )
        return alt
    return src


def session_inputs(cfg: SessionConfig) -> SessionInputs:
    """Resolve the trials by role, the model file, the sha256 of every input file and the body
    mass when the configuration omits it (:func:`msk.personalise.body_mass.resolve_body_mass`:
    ``cfg.subject.mass_kg`` is then set, its source in ``mass``)."""
    from msk.personalise.body_mass import resolve_body_mass

    cfg, body_mass = resolve_body_mass(cfg)
    mass = body_mass.summary()
    fes_trials = cfg.trials_with_role("fes")
    tasks = cfg.trials_with_role("task")
    if not tasks and not fes_trials:
        raise ConfigError(f"{cfg.path}: no trial with role 'task' (nor 'fes')")
    mvc = cfg.trials_with_role("mvc")
    if not tasks:
        files: dict[str, Path] = {f"fes:{tc.name}": tc.file for tc in fes_trials}
        return SessionInputs(
            cfg, False, None, None, (), tuple(mvc), tuple(fes_trials), None, None, files,
            {k: file_sha256(p) for k, p in files.items()}, {}, mass,
        )  # fmt: skip
    task = tasks[0]
    statics = cfg.trials_with_role("static")
    static = statics[0] if statics else None
    mass_trials = cfg.trials_with_role("mass_identification")
    files = {"task": task.file}
    if static is not None:
        files["static"] = static.file
    if task.contact_force is not None:
        files["contact_force"] = task.contact_force
    if task.grf is not None:
        files["grf"] = task.grf
    if task.external_loads is not None:
        files["external_loads"] = task.external_loads
    for tc in (*mass_trials, *mvc, *fes_trials, *cfg.trials_with_role("functional")[:1]):
        files[f"{tc.role}:{tc.name}"] = tc.file
    src = model_source(cfg)
    assert cfg.model is not None  # model_source raised without a [model] table
    files["model"] = src
    if cfg.model.markers is not None:
        files["model_markers"] = cfg.model.markers
    return SessionInputs(
        cfg, True, task, static, tuple(mass_trials), tuple(mvc), tuple(fes_trials), src,
        cfg.model, files, {k: file_sha256(p) for k, p in files.items()},
        {v: k for k, v in cfg.marker_rename.items()}, mass,
    )  # fmt: skip


def plain_settings(cfg: SessionConfig) -> dict[str, Any]:
    """The configuration as JSON-ready values (``summary.json`` ``settings``)."""

    def plain(x: Any) -> Any:
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        if isinstance(x, Mapping):
            return {str(k): plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        if isinstance(x, Path):
            return str(x)
        return x

    return {
        "subject": plain(cfg.subject),
        "model": plain(cfg.model),
        "trials": plain(cfg.trials),
        "markers": {
            "rename": dict(cfg.marker_rename),
            "weights": dict(cfg.marker_weights),
            "move": list(cfg.marker_move),
            "virtual": dict(cfg.marker_virtual),
        },
        "emg": plain(cfg.emg),
        "filters": plain(cfg.filters),
        "optimization": plain(cfg.optimization),
        "fes": plain(cfg.fes),
    }
