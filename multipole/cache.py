"""Private cache folders and authenticated cache entries (the model cache and the numba cache).

The cache root is ``$MULTIPOLE_CACHE`` (default ``~/.cache/multipole``; ``off``, ``0``, ``none`` or
empty: no disk cache).  A cache holds code that is executed later, so it is trusted only when
nobody else can write it:

* :func:`private_dir` creates a folder with mode 0700, or accepts an existing one only if it is a
  directory owned by the current user and not writable by group or others.  Otherwise it prints
  one warning line on stderr naming the folder and the reason, and the caller works without it.
* :func:`user_key` keeps a random 32-byte key in ``<root>/key`` (mode 0600, owner the user; created
  atomically: written under a temporary name and linked into place, so no process ever reads a
  partial key).  :func:`write_entry` and :func:`read_entry` store a payload under an HMAC-SHA256
  over the entry's file name and the payload with that key; an entry whose MAC does not verify
  (damaged, truncated, planted, renamed, or written with another key) reads as missing.
"""
from __future__ import annotations

import atexit
import hashlib
import hmac
import os
import secrets
import shutil
import stat
import sys
import tempfile
from pathlib import Path

#: values of ``MULTIPOLE_CACHE`` that switch the disk cache off
OFF = ("off", "0", "none", "")
#: first line of an entry: this magic, a space, the HMAC in hex
MAGIC = b"multipole-cache-1"
KEY_BYTES = 32

_WARNED: set = set()


def root() -> Path | None:
    """The cache root (``$MULTIPOLE_CACHE``, default ``~/.cache/multipole``), None when off."""
    value = os.environ.get("MULTIPOLE_CACHE", str(Path.home() / ".cache" / "multipole"))
    return None if value.strip().lower() in OFF else Path(value)


def _warn(folder, reason: str) -> None:
    """One line on stderr per folder and reason and process."""
    if (str(folder), reason) not in _WARNED:
        _WARNED.add((str(folder), reason))
        print(f"multipole: warning: cache folder {folder} not used ({reason}); running without a disk cache",
              file=sys.stderr)


def _unsafe(st: os.stat_result, kind: str) -> str | None:
    """Why a file system object with this status may not be trusted (None: it may)."""
    if kind == "dir" and not stat.S_ISDIR(st.st_mode):
        return "not a directory"
    if kind == "file" and not stat.S_ISREG(st.st_mode):
        return "not a regular file"
    if not hasattr(os, "getuid"):          # no POSIX owners and modes (Windows)
        return None
    if st.st_uid != os.getuid():
        return f"owned by uid {st.st_uid}, not by the current user (uid {os.getuid()})"
    mode = stat.S_IMODE(st.st_mode)
    if kind == "dir" and mode & 0o022:
        return f"writable by {'group and others' if mode & 0o022 == 0o022 else 'group' if mode & 0o020 else 'others'} (mode {mode:o})"
    if kind == "file" and mode & 0o077:
        return f"readable or writable by others (mode {mode:o}, must be 600)"
    return None


def private_dir(folder: Path) -> Path | None:
    """``folder``, created with mode 0700 if missing; None (after one warning line) if it cannot
    be created or is not private (see the module docstring)."""
    folder = Path(folder)
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        reason = _unsafe(os.stat(folder), "dir")
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
    if reason is not None:
        _warn(folder, reason)
        return None
    return folder


_PROCESS_DIR: list = []


def process_dir() -> Path:
    """A private folder for this process only (``tempfile.mkdtemp``: mode 0700, a random name,
    created atomically), removed when the process exits."""
    if not _PROCESS_DIR:
        path = Path(tempfile.mkdtemp(prefix="multipole-"))
        atexit.register(shutil.rmtree, path, True)
        _PROCESS_DIR.append(path)
    return _PROCESS_DIR[0]


def user_key(folder: Path) -> bytes | None:
    """The per-user key in ``folder/key`` (created if missing), None (after one warning line) if
    it cannot be made or read or its type, owner, mode or size is wrong."""
    path = Path(folder) / "key"
    if not os.path.lexists(path):
        try:
            fd, tmp = tempfile.mkstemp(dir=folder, prefix=".key.")      # mode 0600
            try:
                os.write(fd, secrets.token_bytes(KEY_BYTES))
                os.fsync(fd)
            finally:
                os.close(fd)
            try:
                os.link(tmp, path)           # atomic; another process may have linked its key first
            except FileExistsError:
                pass
            finally:
                os.unlink(tmp)
        except OSError as exc:
            _warn(folder, f"cannot create the key file: {exc.strerror or type(exc).__name__}")
            return None
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
        try:
            reason = _unsafe(os.fstat(fd), "file")
            data = os.read(fd, KEY_BYTES + 1) if reason is None else b""
        finally:
            os.close(fd)
    except OSError as exc:
        reason = f"cannot read: {exc.strerror or type(exc).__name__}"
    if reason is None and len(data) != KEY_BYTES:
        reason = f"{len(data)} bytes instead of {KEY_BYTES}"
    if reason is not None:
        _warn(folder, f"key file {path.name}: {reason}")
        return None
    return data


def _mac(key: bytes, name: str, payload: bytes) -> str:
    return hmac.new(key, name.encode() + b"\n" + payload, hashlib.sha256).hexdigest()


def read_entry(path: Path, key: bytes) -> bytes | None:
    """The payload of the entry at ``path`` if it is a regular file whose MAC verifies, else None."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read()
    except OSError:
        return None
    finally:
        os.close(fd)
    head, sep, payload = data.partition(b"\n")
    magic, _, mac = head.partition(b" ")
    if not sep or magic != MAGIC:
        return None
    if not hmac.compare_digest(mac, _mac(key, path.name, payload).encode()):
        return None
    return payload


def write_entry(path: Path, key: bytes, payload: bytes) -> None:
    """Write the entry atomically (a temporary file in the same folder renamed into place)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".entry.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(MAGIC + b" " + _mac(key, path.name, payload).encode() + b"\n" + payload)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
