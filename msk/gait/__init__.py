"""Gait analysis: every gait cycle of both legs time-normalised, the gait-lab variables
(three-plane kinematics, foot progression, sagittal moments, the knee adduction moment, joint
powers), spatiotemporal parameters and normative bands."""

__all__: list[str] = []
