"""Marker-based inverse kinematics of a trial, gait events, frames the markers observe, and
coordinate
accelerations made consistent with the low-passed segment centres of mass."""

__all__: list[str] = []
