"""The immutable model: a Pinocchio tree of 1-DOF joints driven by independent coordinates, coupled
joints, the
.osim import, msk's own model files, marker sets, anthropometric tables, knee alignment and the
four-bar knee fit."""

__all__: list[str] = []
