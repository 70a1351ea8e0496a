"""Writing into a folder msk does not trust, and proving what msk itself created there.

A results folder may come from someone else: it can hold symlinks planted where msk writes
(``report.html``'s temporary file, ``report.pdf``, ``.cache``) and folders named like msk's
leftovers. The helpers here never follow a planted link and never act on a folder msk cannot
prove it created:

* :func:`write_file_atomic` writes ``data`` into a new temporary file created with
  ``O_CREAT | O_EXCL | O_NOFOLLOW`` (:func:`tempfile.mkstemp`: a random name, refused if
  anything exists there) in the destination folder, then ``os.replace``\\ s it over the
  destination — a rename replaces a symlink found there, it never writes through it;
* :func:`user_key` is a per-user secret (32 random bytes in ``$XDG_CACHE_HOME/msk/secret.key``,
  created ``0600``; a fresh per-process key when that file cannot be used), kept outside every
  results folder; :func:`mac` authenticates a record with it (HMAC-SHA256, Krawczyk, Bellare
  and Canetti 1997, RFC 2104), so a record found in a received folder that this user's msk did
  not write fails the check;
* :func:`write_marker` / :func:`read_marker` put and check such an authenticated record (a
  random token, the writer's host, boot id, PID namespace and pid) at the top of a folder msk
  creates and may later delete; :func:`writer_may_be_alive` decides from it whether the writer
  can still be running (another host, boot or PID namespace: assumed alive).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import hmac
import json
import os
import secrets
import socket
import stat
import tempfile
from pathlib import Path
from typing import Any

__all__ = [
    "MARKER",
    "host_identity",
    "is_real_dir",
    "mac",
    "read_marker",
    "user_key",
    "write_file_atomic",
    "write_marker",
    "writer_may_be_alive",
]

#: the marker file at the top of a folder msk created (temporary or renamed-away results)
MARKER = ".msk-writer.json"
_KEY_BYTES = 32


def is_real_dir(path: str | Path) -> bool:
    """``path`` is a directory itself, not a symlink to one (``lstat``)."""
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def write_file_atomic(path: str | Path, data: bytes, *, mode: int = 0o644) -> Path:
    """Write ``data`` to ``path`` through a private temporary file in the same folder, created
    exclusively (never an existing file or link), then renamed over ``path`` (a symlink at
    ``path`` is replaced, not followed). The folder is the one ``path``'s parent names (a
    folder given through a link is the user's choice; its last component is never followed)."""
    path = Path(path)
    parent = path.parent.resolve()
    if not parent.is_dir():
        raise OSError(f"{path.parent}: not a folder; not writing {path.name}")
    path = parent / path.name
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, mode & ~mask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return path


def _key_file() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "msk" / "secret.key"


def _read_key(path: Path) -> bytes | None:
    """The key in ``path`` if it is a regular file of ours, private, of the right size."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return None
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fh.fileno())
        uid = getattr(os, "getuid", lambda: st.st_uid)()
        if not stat.S_ISREG(st.st_mode) or st.st_uid != uid or st.st_mode & 0o077:
            return None
        key = fh.read(_KEY_BYTES + 1)
    return key if len(key) == _KEY_BYTES else None


@functools.cache
def _user_key(path_text: str) -> bytes:
    path = Path(path_text)
    key = _read_key(path)
    if key is not None:
        return key
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".secret.", dir=path.parent)  # 0600
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(secrets.token_bytes(_KEY_BYTES))
            os.link(tmp, path)  # atomic and exclusive: a concurrent creator's key wins
        except FileExistsError:
            pass
        finally:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    except OSError:
        pass
    key = _read_key(path)
    # no usable key file (read-only home, a foreign or public file): a key of this process
    # only — what it authenticates is then trusted by this process alone
    return key if key is not None else _process_key()


@functools.cache
def _process_key() -> bytes:
    return secrets.token_bytes(_KEY_BYTES)


def user_key() -> bytes:
    """This user's secret key (see the module docstring)."""
    return _user_key(str(_key_file()))


def mac(*parts: str | bytes) -> str:
    """HMAC-SHA256 under :func:`user_key` of the length-prefixed ``parts`` (hex)."""
    h = hmac.new(user_key(), digestmod=hashlib.sha256)
    for p in parts:
        b = p.encode("utf-8", "surrogatepass") if isinstance(p, str) else p
        h.update(len(b).to_bytes(8, "big"))
        h.update(b)
    return h.hexdigest()


@functools.cache
def host_identity() -> dict[str, str]:
    """Where a process runs: host name, boot id and PID namespace (pids compare only within
    the same three)."""

    def read(path: str, link: bool = False) -> str:
        try:
            return os.readlink(path) if link else Path(path).read_text().strip()
        except OSError:
            return ""

    return {
        "host": socket.gethostname(),
        "boot_id": read("/proc/sys/kernel/random/boot_id"),
        "pid_ns": read("/proc/self/ns/pid", link=True),
    }


_MARKER_FIELDS = ("kind", "target", "pid", "host", "boot_id", "pid_ns", "token")


def _marker_mac(rec: dict[str, Any]) -> str:
    return mac("msk-writer-marker/1", *(str(rec[k]) for k in _MARKER_FIELDS))


def write_marker(folder: str | Path, kind: str, target: str, *, pid: int | None = None) -> None:
    """Mark ``folder`` as created by this process for ``kind`` (``"tmp"``/``"old"``) of the
    results folder named ``target``."""
    rec: dict[str, Any] = {
        "kind": kind,
        "target": target,
        "pid": os.getpid() if pid is None else int(pid),
        **host_identity(),
        "token": secrets.token_hex(16),
    }
    rec["mac"] = _marker_mac(rec)
    write_file_atomic(Path(folder) / MARKER, json.dumps(rec).encode(), mode=0o600)


def read_marker(folder: str | Path, kind: str, target: str) -> dict[str, Any] | None:
    """The marker of ``folder`` if it is a real folder whose marker this user's msk wrote for
    ``kind`` of ``target``; ``None`` otherwise (a folder msk cannot prove it created)."""
    folder = Path(folder)
    if not is_real_dir(folder):
        return None
    try:
        fd = os.open(folder / MARKER, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                return None
            rec = json.loads(fh.read(4096))
    except (OSError, ValueError):
        return None
    if type(rec) is not dict or any(k not in rec for k in (*_MARKER_FIELDS, "mac")):
        return None
    if rec["kind"] != kind or rec["target"] != target or type(rec["pid"]) is not int:
        return None
    if not isinstance(rec["mac"], str) or not hmac.compare_digest(rec["mac"], _marker_mac(rec)):
        return None
    return rec


def writer_may_be_alive(rec: dict[str, Any]) -> bool:
    """Whether the writer of marker ``rec`` may still be running: always when it ran on
    another host, boot or PID namespace (its pid means nothing here), else when its process
    exists (or cannot be checked)."""
    if any(rec.get(k) != v or not v for k, v in host_identity().items() if k != "host"):
        return True
    if rec.get("host") != host_identity()["host"]:
        return True
    pid = rec["pid"]
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError, OverflowError):
        return True
    return True
