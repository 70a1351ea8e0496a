"""The results contract: what ``msk run`` writes for one session, and how to read it back.

One folder per session (DESIGN.md "Results a run writes")::

    <out>/
      tables/<quantity>.csv     first column ``time`` (s), then named columns, SI units
      tables/<quantity>.sto     the same table as an OpenSim 4 storage file (``q.mot`` for the
                                coordinates, angles in degrees as OpenSim expects): its rows
                                and columns without a missing value, so that OpenSim's legacy
                                ``Storage`` (GUI, AnalyzeTool) reads it to the last row; the
                                rows and columns left out are listed in its header
                                (``msk_rows_left_out``: row indices of the CSV,
                                ``msk_columns_left_out``; :mod:`msk.io.storage_twin`)
      opensim/markers.trc       the task's markers in the model frame (OpenSim's ground, the
                                frame of ``q.mot``), mm, model marker names
      opensim/grf.mot           the ground reactions msk applied, per body (``<body>_force_v*``,
                                ``_force_p*``, ``_torque_*``; N, m, N·m; in ground)
      opensim/external_loads.xml  OpenSim ExternalLoads applying ``grf.mot`` to those bodies
      opensim/model.osim        the scaled model msk used (bodies with the inertias of
                                ``joint_torques``, joints, coordinates, placed markers,
                                muscles); with ``tables/q.mot`` these are the
                                inputs of OpenSim's inverse kinematics and dynamics
                                (:mod:`msk.pipeline.opensim_export`; ``summary.json`` ``opensim``)
      summary.json              versions, inputs with sha256, settings, quality figures, stage
                                timings, stages not available, identified parameters: the
                                typed, versioned :class:`msk.results.summary.Summary` (its
                                ``format``
                                key is the schema version)
      report.html               the clinician report (self-contained)
      report.pdf                when headless Chromium is available

Quantities (:data:`TABLES`): ``q`` (rad / m), ``joint_torques`` (N·m / N, one column per
coordinate, the pelvis ones being the residuals), ``residuals`` (``force_x…z`` N and
``moment_x…z`` N·m about the pelvis origin, world axes of the model frame), ``muscle_forces``
(N), ``activations`` (1), ``knee_contact`` (``<variant>_x/_y/_z``: force of the femur on the tibia
in the knee joint frame fixed in the tibia, N; ``<variant>_total`` its magnitude, N, and
``_total_bw`` in body weights; variants ``generic`` and ``subject_specific``; ``measured_total``
the implant's force on the same time base, NaN outside the measured cycle),
``inertial_parameters`` and ``strength``, ``gait_cycles_left`` and ``gait_cycles_right`` (every
complete gait cycle of the side, 101 rows per cycle: :mod:`msk.gait.cycles`; read typed by
:meth:`SessionResults.gait_cycles`; the spatiotemporal parameters are in ``summary.json``
``gait``, :meth:`SessionResults.spatiotemporal`). ``inertial_parameters`` and ``strength`` are
not time series: they are one row whose ``time`` is the start (s) of the data they were
identified from, with columns ``<segment>.<parameter>`` (Pinocchio order ``m, mx, my, mz, Ixx,
Ixy, Iyy, Ixz, Iyz, Izz`` in kg, kg·m, kg·m²) and ``<group>.<figure>`` (factor ×generic, CI
bounds, F_iso in N). A readable copy of both lives in ``summary.json``.

FES sessions (``role = "fes"`` trials, Benoussaad et al. 2013) add ``fes_parameters`` (one row,
``time`` 0, columns ``<group>.<parameter>`` of the identified quadriceps–shank model in SI:
``geometry.L_ext`` m, ``geometry.r_q`` m, ``knee.J`` kg·m², ``knee.B`` N·m·s/rad, ``knee.K``
N·m/rad, ``muscle.F_cm`` N, ``muscle.K_cm`` N/m, ``muscle.L_c0`` m, ``muscle.b`` 1, ``muscle.k_s``
N/m, ``muscle.L_s`` m, ``recruitment.c1…c3`` 1; the units are repeated in ``summary.json`` ``fes``),
``fes_steps`` (one row, ``time`` 0, ``<step>.nrmsd_pct`` and ``<step>.nrmse_pct`` per protocol
step, Benoussaad et al. 2013, Table 2 rows) and ``fes_validation`` (time series of the
cross-validation trial: ``knee_angle_measured``, ``knee_angle_simulated`` and
``knee_angle_simulated_k_s0`` before the ``k_s`` identification, rad, 0 = full extension).

Writing is atomic for the whole folder (:func:`write_session`): everything goes into a temporary
sibling folder that replaces ``<out>`` by a rename at the very end, so a run that fails never
leaves a half-written table or report behind (the previous results, if any, stay intact).
The replacement is two renames (``<out>`` → ``.<out>.old-<pid>-<random>``, then the temporary
folder → ``<out>``); a process killed between them leaves ``<out>`` absent. The next write to
(or check of) ``<out>`` recovers (:func:`recover_interrupted_write`): the previous results are
put back, with the stage cache, and the leftovers of dead writers are removed — an interrupted
run never reported success, so its half-published results are not kept. Both hidden folders
carry a marker authenticated with the user's key (:mod:`msk._runtime.secure`): a folder msk cannot
prove it created is never removed, and a folder holding anything msk did not write (a user's
file in ``tables/``, a symbolic link) is never replaced.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from msk._runtime.secure import MARKER, is_real_dir, read_marker, write_marker, writer_may_be_alive
from msk.exceptions import FileFormatError, MissingDataError, SummaryError
from msk.gait.cycles import GaitCycles
from msk.gait.spatiotemporal import Spatiotemporal
from msk.io.opensim_files import write_sto
from msk.io.storage_twin import storage_twin
from msk.io.tables import Table, read_csv_table, write_csv_table
from msk.results.summary import SUMMARY_FORMAT, Summary, as_summary, json_default, strict_json

__all__ = [
    "SUMMARY_FORMAT",
    "TABLES",
    "SessionResults",
    "Summary",
    "check_replaceable",
    "json_default",
    "pooled_gait",
    "read_session",
    "read_task_trials",
    "recover_interrupted_write",
    "write_session",
]

#: The tables of the contract, in the order a reader meets them.
TABLES: tuple[str, ...] = (
    "q",
    "joint_torques",
    "residuals",
    "muscle_forces",
    "activations",
    "knee_contact",
    "inertial_parameters",
    "strength",
    "fes_parameters",
    "fes_steps",
    "fes_validation",
    "gait_cycles_left",
    "gait_cycles_right",
)


@dataclass(frozen=True, init=False)
class SessionResults:
    """The results of one session as read from (or about to be written to) its folder.

    ``tables`` maps a quantity name to its :class:`~msk.io.tables.Table` (SI);
    ``summary`` is the ``summary.json`` content as a :class:`~msk.results.summary.Summary` (a plain
    mapping — the summary the pipeline assembles — is converted by
    :func:`~msk.results.summary.as_summary`: numpy values as JSON, non-finite numbers as ``None``);
    ``path`` the folder (``None`` before writing). ``angle_columns`` names the columns of ``q``
    that are rotations (written in degrees in the ``.mot`` twin).
    """

    tables: Mapping[str, Table]
    summary: Summary
    path: Path | None
    angle_columns: tuple[str, ...]
    extra_files: Mapping[str, bytes]

    def __init__(
        self,
        tables: Mapping[str, Table],
        summary: Summary | Mapping[str, Any],
        path: Path | None = None,
        angle_columns: tuple[str, ...] = (),
        extra_files: Mapping[str, bytes] | None = None,
    ) -> None:
        object.__setattr__(self, "tables", tables)
        object.__setattr__(self, "summary", as_summary(summary))
        object.__setattr__(self, "path", path)
        object.__setattr__(self, "angle_columns", tuple(angle_columns))
        object.__setattr__(self, "extra_files", {} if extra_files is None else extra_files)

    def __reduce__(self) -> tuple[Any, ...]:
        # to a forked figure process of the same run (msk._runtime.fork): the summary as its plain
        # JSON tree (its records hold read-only mapping proxies, which pickle refuses)
        args = (dict(self.tables), self.summary.to_dict(), self.path, self.angle_columns)
        return (SessionResults, (*args, dict(self.extra_files)))

    def table(self, name: str) -> Table:
        try:
            return self.tables[name]
        except KeyError:
            raise MissingDataError(
                f"session {self.summary.session!r}: no table {name!r} (have {sorted(self.tables)})"
            ) from None

    def has(self, name: str) -> bool:
        return name in self.tables

    def gait_cycles(self) -> GaitCycles | None:
        """Every normalised gait cycle of both sides (:class:`msk.gait.cycles.GaitCycles`,
        from ``tables/gait_cycles_<side>.csv``; a side without a complete cycle has no table),
        None when the session has none."""
        if not (self.has("gait_cycles_left") or self.has("gait_cycles_right")):
            return None
        return GaitCycles.from_tables(self.tables, trial=self.summary.trial or "")

    def spatiotemporal(self) -> Spatiotemporal | None:
        """The spatiotemporal parameters per side and stride
        (:class:`msk.gait.spatiotemporal.Spatiotemporal`, from ``summary.json`` ``gait``),
        None when the session has none."""
        gait = self.summary.gait
        if gait is None or gait.spatiotemporal is None:
            return None
        return Spatiotemporal.from_summary(gait.spatiotemporal, source=gait.heel_source or "")


def _write_tables(folder: Path, results: SessionResults) -> list[str]:
    tdir = folder / "tables"
    tdir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, tab in results.tables.items():
        write_csv_table(tdir / f"{name}.csv", tab)
        # the rows and columns OpenSim's Storage reads (no NaN), the rest listed in its header
        twin = storage_twin(Table(time=tab.time, data=tab.data, columns=tab.columns, name=name))
        if name == "q":
            angles = tuple(c for c in results.angle_columns if c in twin.table.columns)
            write_sto(
                tdir / "q.mot",
                twin.table,
                in_degrees=True,
                angle_columns=angles,
                name="q",
                header=twin.header,
            )
        else:
            write_sto(tdir / f"{name}.sto", twin.table, name=name, header=twin.header)
        written.append(name)
    return written


def write_session(
    out_dir: str | Path,
    results: SessionResults,
    *,
    report: Callable[[SessionResults, Path], None] | None = None,
    keep: Sequence[str] = (".cache",),
) -> Path:
    """Write ``results`` as the session folder ``out_dir``, atomically.

    Tables, twins, ``summary.json`` and whatever ``report(results, folder)`` writes go into a
    temporary sibling folder; entries of the old folder named in ``keep`` (the stage cache) are
    moved over; then the temporary folder replaces ``out_dir``. On any exception the temporary
    folder is removed and ``out_dir`` is left as it was.
    """
    out = Path(out_dir).resolve()
    check_replaceable(out, keep)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-{os.getpid()}-", dir=out.parent))
    try:
        write_marker(tmp, "tmp", out.name)  # proof that this folder is msk's (recovery)
        written = _write_tables(tmp, results)
        for rel, blob in results.extra_files.items():
            p = tmp / rel
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(blob)
        summary = results.summary.to_dict()
        summary["format"] = SUMMARY_FORMAT
        summary["tables"] = written
        text = json.dumps(strict_json(summary), indent=2, default=json_default, allow_nan=False)
        (tmp / "summary.json").write_text(text + "\n", encoding="utf-8")
        if report is not None:
            # the report sees exactly what a reader of the folder sees
            report(
                SessionResults(results.tables, Summary.from_json(text), tmp, results.angle_columns),
                tmp,
            )
        _publishable(tmp)
        old = None
        if out.exists():
            for name in keep:
                src = out / name
                if is_real_dir(src):  # a symlink planted as the cache is not carried over
                    os.replace(src, tmp / name)
            old = out.parent / f".{out.name}.old-{os.getpid()}-{secrets.token_hex(8)}"
            write_marker(out, "old", out.name)
            os.replace(out, old)
        os.replace(tmp, out)
        (out / MARKER).unlink(missing_ok=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        # put the cache back if it was moved, then drop the temporary folder
        for name in keep:
            if is_real_dir(tmp / name) and out.exists() and not (out / name).exists():
                os.replace(tmp / name, out / name)
        if out.is_dir():
            (out / MARKER).unlink(missing_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


#: what a session folder written by :func:`write_session` holds (besides ``keep``)
SESSION_ENTRIES = frozenset(
    {"summary.json", "report.html", "report.pdf", "tables", "opensim", MARKER}
)


def recover_interrupted_write(out_dir: str | Path, keep: Sequence[str] = (".cache",)) -> list[str]:
    """Recover ``out_dir`` from a :func:`write_session` killed between its two renames, and
    remove what dead writers left beside it.

    Only folders msk can prove it created are touched: a real folder (not a symlink) named
    ``.<out>.old-*`` or ``.<out>.tmp-*`` holding a marker that this user's msk wrote for
    ``<out>`` (:func:`msk._runtime.secure.read_marker`: authenticated with the user's key), whose
    writer is gone (same host, boot and PID namespace, process absent: a writer elsewhere is
    assumed alive). Then:

    * ``.<out>.old-*`` (the previous results, renamed away): when ``<out>`` is absent it is
      renamed back to ``<out>``; otherwise the swap had completed and it is removed;
    * ``.<out>.tmp-*`` (a temporary folder: unfinished, or finished but never published):
      the ``keep`` entries in it (the stage cache) go back into ``<out>`` when ``<out>``
      lacks them; then it is removed.

    Returns one line per action (empty when there was nothing to do)."""
    out = Path(out_dir).resolve()
    parent = out.parent
    if not parent.is_dir():
        return []
    done: list[str] = []
    old_prefix, tmp_prefix = f".{out.name}.old-", f".{out.name}.tmp-"
    try:
        entries = sorted(parent.iterdir())
    except OSError:
        return []

    def proven(p: Path, kind: str) -> bool:
        rec = read_marker(p, kind, out.name)
        return rec is not None and not writer_may_be_alive(rec)

    olds = [p for p in entries if p.name.startswith(old_prefix) and proven(p, "old")]
    tmps = [p for p in entries if p.name.startswith(tmp_prefix) and proven(p, "tmp")]
    for old in olds:
        if not os.path.lexists(out):
            os.rename(old, out)
            (out / MARKER).unlink(missing_ok=True)
            done.append(f"restored {out} from {old.name} (a run was interrupted replacing it)")
        else:
            shutil.rmtree(old, ignore_errors=True)
            done.append(f"removed {old.name} (left by an interrupted run)")
    for tmp in tmps:
        if is_real_dir(out):
            for name in keep:
                if is_real_dir(tmp / name) and not os.path.lexists(out / name):
                    os.replace(tmp / name, out / name)
        shutil.rmtree(tmp, ignore_errors=True)
        done.append(f"removed {tmp.name} (temporary folder of an interrupted run)")
    return done


def check_replaceable(out_dir: str | Path, keep: Sequence[str] = (".cache",)) -> None:
    """Refuse to replace a folder unless nothing but msk's own output would be lost: it must
    be absent, empty (but for ``keep``), or an msk session folder — a ``summary.json`` of
    format :data:`SUMMARY_FORMAT` and no entry msk did not write (:data:`SESSION_ENTRIES`;
    in ``tables/`` only the tables its summary lists, as ``.csv`` and their ``.sto``/``.mot``
    twins; no symbolic link anywhere but as a ``keep`` entry, which is then not carried
    over). A folder that is refused is refused before anything is recovered or removed;
    otherwise an interrupted write is recovered (:func:`recover_interrupted_write`) and the
    folder it restores is checked in turn."""
    out = Path(out_dir)
    if os.path.lexists(out):
        _check_folder(out, keep)  # refused: nothing is touched
    recover_interrupted_write(out, keep)
    if os.path.lexists(out):
        _check_folder(out, keep)


def _table_files(names: Any) -> set[str]:
    """The files of ``tables/`` a summary's ``tables`` list accounts for."""
    if not isinstance(names, list):
        return set()
    out = set()
    for n in names:
        if isinstance(n, str) and n in TABLES:
            out |= {f"{n}.csv", "q.mot" if n == "q" else f"{n}.sto"}
    return out


def _check_folder(out: Path, keep: Sequence[str]) -> None:
    if out.is_symlink() or not out.is_dir():
        raise FileFormatError(f"{out}: exists and is not a folder")
    other = sorted(p.name for p in out.iterdir() if p.name not in keep)
    if not other:
        return
    spath = out / "summary.json"
    if spath.is_symlink() or not spath.is_file():
        raise FileFormatError(
            f"{out}: not an msk session folder (no summary.json) and not empty "
            f"({', '.join(other[:3])}…); choose another --out"
        )
    try:
        data = json.loads(spath.read_text(encoding="utf-8"))
        fmt, listed = data.get("format"), data.get("tables")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError, RecursionError):
        fmt, listed = None, None
    if fmt != SUMMARY_FORMAT:
        raise FileFormatError(
            f"{spath}: not an msk session summary (format {fmt!r}, expected "
            f"{SUMMARY_FORMAT!r}); refusing to replace {out}: choose another --out"
        )
    foreign = [n for n in other if n not in SESSION_ENTRIES or (out / n).is_symlink()]
    tables = out / "tables"
    if is_real_dir(tables):
        ours = _table_files(listed)
        foreign += [
            f"tables/{p.name}"
            for p in tables.iterdir()
            if p.is_symlink() or not p.is_file() or p.name not in ours
        ]
    if foreign:
        raise FileFormatError(
            f"{out}: holds files msk did not write ({', '.join(sorted(foreign)[:3])}); "
            "refusing to replace it: move them or choose another --out"
        )


def _publishable(folder: Path) -> None:
    """Ordinary permissions (temporary files are created private): dirs 0755, files 0644,
    both masked by the process umask."""
    mask = os.umask(0)
    os.umask(mask)
    for p in [folder, *folder.rglob("*")]:
        p.chmod((0o755 if p.is_dir() else 0o644) & ~mask)


def read_session(path: str | Path) -> SessionResults:
    """Read a session folder written by :func:`write_session` (``msk run``); its ``summary``
    is a :class:`~msk.results.summary.Summary`. A summary of a newer schema version, without a
    required key or with a value of the wrong type raises a
    :class:`~msk.exceptions.SummaryError` naming the file and the key."""
    folder = Path(path)
    spath = folder / "summary.json"
    if not spath.is_file():
        raise FileFormatError(f"{folder}: not an msk session folder (no summary.json)")
    try:
        summary = Summary.from_json(spath.read_text(encoding="utf-8"))
    except SummaryError as exc:
        raise type(exc)(f"{spath}: {exc}", key=exc.key) from None
    tables = {}
    for name in summary.tables or ():
        tables[name] = read_csv_table(folder / "tables" / f"{name}.csv")
    angles = summary.angle_columns or ()
    return SessionResults(tables=tables, summary=summary, path=folder, angle_columns=angles)


def read_task_trials(path: str | Path) -> list[SessionResults]:
    """The results of every task trial of a session as ``msk run`` wrote them
    (:func:`msk.pipeline.run_task_trials`): ``path`` itself when it is a session folder, else
    each of its subfolders that is one (several task trials: ``<out>/<trial name>/``), in name
    order."""
    folder = Path(path)
    if (folder / "summary.json").is_file():
        return [read_session(folder)]
    subs = (
        sorted(p for p in folder.iterdir() if (p / "summary.json").is_file())
        if folder.is_dir()
        else []
    )
    if not subs:
        raise FileFormatError(f"{folder}: neither a session folder nor one of task-trial folders")
    return [read_session(p) for p in subs]


def pooled_gait(
    sessions: Sequence[SessionResults],
) -> tuple[GaitCycles | None, Spatiotemporal | None]:
    """Every gait cycle and stride of ``sessions`` (e.g. the task trials of
    :func:`read_task_trials`) pooled per side (:meth:`GaitCycles.concatenate`,
    :meth:`Spatiotemporal.concatenate`): mean ± SD across cycles and trials; None where no
    session has any."""
    cycles = [c for s in sessions if (c := s.gait_cycles()) is not None]
    strides = [st for s in sessions if (st := s.spatiotemporal()) is not None]
    return (
        GaitCycles.concatenate(cycles) if cycles else None,
        Spatiotemporal.concatenate(strides) if strides else None,
    )
