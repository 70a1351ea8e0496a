"""The report's sections, one module each, in the order of a clinical gait report: session and
data quality → spatiotemporal parameters → kinematics and kinetics grids → knee loads → muscle
forces → strength → mass distribution → (FES) → methods → references.

:data:`SECTIONS` is the registry: every member of the family, sorted by its ``order``; a
section's number is derived when the report is rendered (the sections that have something for
the session, numbered 1, 2, 3 …)."""

from __future__ import annotations

from msk.report.sections.base import ReportContext, Section
from msk.report.sections.fes import FesSection
from msk.report.sections.kinematics import Kinematics, Kinetics
from msk.report.sections.knee_loads import KneeLoads
from msk.report.sections.mass import MassSection
from msk.report.sections.methods import Methods
from msk.report.sections.muscle_forces import MuscleForces
from msk.report.sections.references import References
from msk.report.sections.session import SessionSummary
from msk.report.sections.spatiotemporal import Spatiotemporal
from msk.report.sections.strength import StrengthSection

__all__ = ["SECTIONS", "ReportContext", "Section", "register"]

SECTIONS: list[Section] = []


def register(section: Section) -> Section:
    """Add ``section`` to :data:`SECTIONS` (kept sorted by ``order``; keys are unique)."""
    if any(s.key == section.key for s in SECTIONS):
        raise ValueError(f"a report section {section.key!r} is already registered")
    SECTIONS.append(section)
    SECTIONS.sort(key=lambda s: s.order)
    return section


for _section in (
    SessionSummary(),
    Spatiotemporal(),
    Kinematics(),
    Kinetics(),
    KneeLoads(),
    MuscleForces(),
    StrengthSection(),
    MassSection(),
    FesSection(),
    Methods(),
    References(),
):
    register(_section)
