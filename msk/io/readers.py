"""Trial readers by file suffix: :func:`read_trial` reads any motion file msk knows as a
:class:`msk.trial.Trial`.

The family: a :class:`TrialReader` (suffix, reading function, one-line description) per format,
each function in its own format module (``.c3d``: :func:`msk.io.c3d.read_c3d`; ``.trc``:
:func:`msk.io.opensim_files.read_trc_trial`, a markers-only trial in OpenSim's ground frame),
and one registry declared here (:data:`TRIAL_READERS`; :func:`register_trial_reader` adds one).
A file whose suffix has no reader raises :class:`~msk.exceptions.FileFormatError` naming the
file and the known suffixes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from msk.exceptions import FileFormatError
from msk.io.c3d import read_c3d
from msk.io.opensim_files import read_trc_trial
from msk.trial import Trial

__all__ = [
    "TRIAL_READERS",
    "TrialReader",
    "read_trial",
    "register_trial_reader",
    "trial_reader",
    "trial_suffixes",
]


@dataclass(frozen=True)
class TrialReader:
    """A trial format: files ending in ``suffix`` (lower case, with the dot) are read by
    ``read(path)`` into a :class:`~msk.trial.Trial`."""

    suffix: str
    read: Callable[[Path], Trial]
    description: str = ""


#: The registry: lower-case suffix → reader.
TRIAL_READERS: dict[str, TrialReader] = {}


def register_trial_reader(reader: TrialReader) -> None:
    """Add (or replace) the reader of ``reader.suffix`` (matched case-insensitively)."""
    suffix = reader.suffix.lower()
    if not suffix.startswith(".") or len(suffix) < 2:
        raise FileFormatError(f"trial reader suffix must look like '.ext', got {reader.suffix!r}")
    TRIAL_READERS[suffix] = reader


def trial_suffixes() -> tuple[str, ...]:
    """The suffixes :func:`read_trial` reads, sorted."""
    return tuple(sorted(TRIAL_READERS))


def trial_reader(path: str | Path) -> TrialReader:
    """The reader of ``path`` by its suffix; :class:`FileFormatError` naming the file and the
    known suffixes when there is none."""
    path = Path(path)
    try:
        return TRIAL_READERS[path.suffix.lower()]
    except KeyError:
        raise FileFormatError(
            f"{path}: no trial reader for suffix {path.suffix or '(none)'!r}; "
            f"known: {', '.join(trial_suffixes())}"
        ) from None


def read_trial(path: str | Path) -> Trial:
    """Read a motion trial with the reader of its suffix (``.c3d``, ``.trc``), SI units, in the
    file's own frame (a C3D's lab, a TRC's OpenSim ground: +y up)."""
    path = Path(path)
    return trial_reader(path).read(path)


register_trial_reader(
    TrialReader(".c3d", read_c3d, "C3D: markers, model outputs, analogs, force plates, events")
)
register_trial_reader(
    TrialReader(".trc", read_trc_trial, "OpenSim TRC: markers only, OpenSim ground (+y up)")
)
