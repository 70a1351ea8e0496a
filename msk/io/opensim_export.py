"""What an OpenSim user needs to go on in OpenSim from a run: the task's markers as a ``.trc``,
the ground reactions msk applied as a ``.mot`` with the ExternalLoads ``.xml`` that applies them
to the bodies msk assigned them to.

Frames and units are the model's (OpenSim's ground: the frame of ``tables/q.mot``): markers in
mm (``Units=mm``) under the model's marker names where the configuration renames them; forces
in N, points in m, torques in N·m, all expressed in ground.

The ground reactions are msk's per-body external wrenches
(:class:`msk.dynamics.loads.ExternalLoads`,
on the kinematics' time, after the plate assignment and its low-pass): for body b the force
F_b, a point p_b (the centre of pressure where defined) and the torque about it,
T_b = M_O,b − p_b × F_b (M_O,b: the moment about the ground origin). OpenSim's
``ExternalForce`` applies F_b at p_b plus T_b, the same wrench. Where p_b is undefined
(unloaded, or a load without a centre of pressure) the point written is the ground origin and
the torque M_O,b: still the same wrench (zero when unloaded), and no missing value, which
OpenSim's ``Storage`` (what ExternalLoads reads its data with) cannot read
(:mod:`msk.io.storage_twin`). Frames whose load msk does not know (non-finite force) are left
out and listed in the file's header. Column names follow OpenSim's ``<name>_force_v[xyz]``,
``<name>_force_p[xyz]``, ``<name>_torque_[xyz]`` with ``<name>`` the body.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import ArrayLike

from msk.exceptions import FileFormatError
from msk.io.opensim_files import write_sto, write_trc
from msk.io.storage_twin import storage_twin
from msk.io.tables import Table, write_text_atomic

__all__ = ["grf_table", "write_external_loads_xml", "write_grf_mot", "write_markers_trc"]


def grf_table(
    time: ArrayLike,
    bodies: Sequence[str],
    force: ArrayLike,
    moment: ArrayLike,
    point: ArrayLike,
    *,
    name: str = "grf",
) -> Table:
    """The ground reactions per body as an OpenSim GRF table (module docstring): ``force``,
    ``moment`` (about the ground origin) and ``point`` are (N, B, 3) in ground; NaN points
    are written as the origin with the moment about it."""
    t = np.asarray(time, dtype=float).reshape(-1)
    f = np.asarray(force, dtype=float)
    m = np.asarray(moment, dtype=float)
    p = np.asarray(point, dtype=float)
    shape = (t.size, len(bodies), 3)
    for what, arr in (("force", f), ("moment", m), ("point", p)):
        if arr.shape != shape:
            raise FileFormatError(f"GRF table {name!r}: {what} shape {arr.shape}, expected {shape}")
    defined = np.isfinite(p).all(axis=2, keepdims=True)
    p_out = np.where(defined, p, 0.0)
    torque = m - np.cross(p_out, f)
    cols: list[str] = []
    data: list[np.ndarray] = []
    for b, body in enumerate(bodies):
        cols += [f"{body}_force_v{a}" for a in "xyz"]
        cols += [f"{body}_force_p{a}" for a in "xyz"]
        cols += [f"{body}_torque_{a}" for a in "xyz"]
        data += [f[:, b], p_out[:, b], torque[:, b]]
    values = np.concatenate(data, axis=1) if data else np.zeros((t.size, 0))
    return Table(t, values, tuple(cols), name)


def write_grf_mot(path: str | Path, table: Table) -> tuple[Path, Table]:
    """Write :func:`grf_table`'s table as a ``.mot`` OpenSim's ``Storage`` reads to the last row
    (rows with a missing value left out and listed: :func:`msk.io.storage_twin.storage_twin`).
    Returns the path and the rows written."""
    twin = storage_twin(table)
    p = write_sto(path, twin.table, name=table.name or "grf", header=twin.header)
    return p, twin.table


def write_external_loads_xml(
    path: str | Path, datafile: str, bodies: Sequence[str], *, name: str = "externalloads"
) -> Path:
    """An OpenSim 4 ``ExternalLoads`` file applying each body's columns of the GRF file
    ``datafile`` (a path relative to the xml, as OpenSim resolves it) to that body, force and
    point expressed in ground."""
    items = []
    for body in bodies:
        b = escape(body)
        items.append(
            f'\t\t\t<ExternalForce name="{b}_ground_reaction">\n'
            "\t\t\t\t<isDisabled>false</isDisabled>\n"
            f"\t\t\t\t<applied_to_body>{b}</applied_to_body>\n"
            "\t\t\t\t<force_expressed_in_body>ground</force_expressed_in_body>\n"
            "\t\t\t\t<point_expressed_in_body>ground</point_expressed_in_body>\n"
            f"\t\t\t\t<force_identifier>{b}_force_v</force_identifier>\n"
            f"\t\t\t\t<point_identifier>{b}_force_p</point_identifier>\n"
            f"\t\t\t\t<torque_identifier>{b}_torque_</torque_identifier>\n"
            f"\t\t\t\t<data_source_name>{escape(datafile)}</data_source_name>\n"
            "\t\t\t</ExternalForce>\n"
        )
    text = (
        '<?xml version="1.0" encoding="UTF-8" ?>\n<OpenSimDocument Version="40000">\n'
        f'\t<ExternalLoads name="{escape(name)}">\n\t\t<objects>\n'
        + "".join(items)
        + "\t\t</objects>\n\t\t<groups />\n"
        + f"\t\t<datafile>{escape(datafile)}</datafile>\n"
        "\t</ExternalLoads>\n</OpenSimDocument>\n"
    )
    return write_text_atomic(path, text)


def write_markers_trc(
    path: str | Path,
    time: ArrayLike,
    markers: ArrayLike,
    labels: Sequence[str],
    *,
    rate_hz: float | None = None,
) -> Path:
    """The markers (N, M, 3) in m, ground frame, as a TRC in mm (gaps written ``NaN``, which
    OpenSim's TRC reader takes as missing). Exact-zero samples (a C3D's gap) are gaps."""
    x = np.array(markers, dtype=float)
    x[(x == 0.0).all(axis=2)] = np.nan
    return write_trc(path, time=time, markers=x, labels=labels, units="mm", rate_hz=rate_hz)
