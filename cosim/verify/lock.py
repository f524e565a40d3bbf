"""One campaign at a time in a report folder: ``<report>/campaign.lock``.

A campaign takes the lock before it touches the folder and releases it at its end, on
an error and on Ctrl-C alike. The lock file names its owner (pid, host, start time and
command line) as JSON; the lock itself is an exclusive :func:`fcntl.flock` on that file,
which the kernel drops when the owner dies, however it dies. So:

- a second campaign on the folder cannot take the lock and is refused in one line that
  names the owner (a :class:`~cosim.verify.workers.CampaignError`, exit code 3);
- a lock file whose owner was killed (SIGKILL, a power cut) can be locked again: its
  owner, on this host, is gone, and the new campaign takes it over with a note;
- a lock file left by a process on *another* host is not taken over (this host cannot
  tell whether that process still runs): the message says to delete the file if the
  campaign there has ended.

Where the file system has no ``flock`` (some network file systems), the owner's pid is
checked instead (alive on this host: refused). The lock is reentrant within one process
(``ins-cosim verify`` holds it around the campaign and its reports; the campaign takes
it again).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import inspect
import json
import os
import socket
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, TypeVar

from cosim.verify.workers import CampaignError

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]

LOCK_FILE = "campaign.lock"

F = TypeVar("F", bound=Callable[..., Any])


class StaleLockNote(UserWarning):
    """A lock left by a campaign that no longer runs was taken over."""


@dataclass
class _Held:
    fd: int
    path: Path
    count: int
    created_folder: bool


_HELD: dict[str, _Held] = {}
_GUARD = threading.Lock()


def _process_start(pid: int) -> int | None:
    """Start time of a process in clock ticks since boot (Linux), to tell a reused pid."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            # the command name (field 2) may hold spaces: the fields after it follow ")"
            return int(fh.read().rsplit(b")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def _owner() -> dict[str, Any]:
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": datetime.now(UTC).isoformat(timespec="seconds"),
        "process_start": _process_start(os.getpid()),
        "command": " ".join(os.path.basename(a) if i == 0 else a for i, a in enumerate(sys.argv))[
            :300
        ],
    }


def read_lock(folder: str | Path) -> dict[str, Any] | None:
    """The owner recorded in a report folder's lock file.

    Parameters
    ----------
    folder : str or Path
        A ``--report`` folder.

    Returns
    -------
    dict or None
        ``pid``, ``host``, ``started`` (ISO 8601, UTC), ``process_start`` and ``command``;
        None when there is no lock file or it holds no owner (yet).
    """
    path = Path(folder) / LOCK_FILE
    for _ in range(20):  # the owner writes right after creating it: wait a moment
        try:
            text = path.read_text()
        except FileNotFoundError:
            return None
        except OSError:
            text = ""
        if text.strip():
            try:
                data = json.loads(text)
            except ValueError:
                data = None
            if isinstance(data, dict):
                return data
        time.sleep(0.05)
    return None


def _describe(owner: dict[str, Any] | None) -> str:
    if not owner:
        return "a process that has not written its name yet"
    command = f" ({owner['command']})" if owner.get("command") else ""
    return (
        f"pid {owner.get('pid')} on host {owner.get('host')} since "
        f"{str(owner.get('started', '?')).replace('T', ' ').replace('+00:00', ' UTC')}{command}"
    )


def _refuse(folder: Path, owner: dict[str, Any] | None, elsewhere: bool = False) -> CampaignError:
    if elsewhere:
        how = (
            f"this host cannot tell whether it still runs: if it has ended, delete "
            f"{folder / LOCK_FILE}, else wait for it or use another --report folder"
        )
    else:
        how = "wait for it to end, or use another --report folder"
    return CampaignError(
        f"report folder {folder} is in use by another campaign: {_describe(owner)}; {how}"
    )


def _flock(fd: int) -> bool | None:
    """True: locked; False: another process holds it; None: no flock on this file system."""
    if fcntl is None:  # pragma: no cover
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EACCES):
            return False
        return None  # ENOLCK, EOPNOTSUPP, ...
    return True


def _acquire(folder: Path) -> _Held:
    created = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_FILE
    me = socket.gethostname()
    for _ in range(10):
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            got = _flock(fd)
            if got is False:
                raise _refuse(folder, read_lock(folder))
            # the file may have been released (unlinked) between open and flock: retry
            # on the file that is at the path now
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(path))
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            old = None
            size = os.fstat(fd).st_size
            if size:
                with contextlib.suppress(ValueError, UnicodeDecodeError):
                    old = json.loads(os.pread(fd, min(size, 65536), 0).decode())
                if not isinstance(old, dict):
                    old = {}
            if old is not None:
                pid = old.get("pid")
                if old.get("host") not in (None, me):
                    raise _refuse(folder, old, elsewhere=True)
                if got is None and isinstance(pid, int) and pid != os.getpid() and _alive(pid):
                    start = old.get("process_start")
                    if start is None or start == _process_start(pid):
                        raise _refuse(folder, old)
                if old:
                    warnings.warn(
                        f"report folder {folder}: took over the lock of a campaign that no "
                        f"longer runs ({_describe(old)})",
                        StaleLockNote,
                        stacklevel=4,
                    )
            data = (json.dumps(_owner()) + "\n").encode()
            os.ftruncate(fd, 0)
            os.pwrite(fd, data, 0)
            return _Held(fd, path, 1, created)
        except BaseException:
            with contextlib.suppress(OSError):
                os.close(fd)
            if created:
                with contextlib.suppress(OSError):
                    folder.rmdir()
            raise
    raise CampaignError(f"report folder {folder}: could not take {LOCK_FILE} (it keeps changing)")


def _release(held: _Held) -> None:
    with contextlib.suppress(OSError):
        held.path.unlink()  # unlinked while locked: a waiter sees a new file
    with contextlib.suppress(OSError):
        os.close(held.fd)
    if held.created_folder:  # a campaign refused before its first run leaves no folder
        with contextlib.suppress(OSError):
            held.path.parent.rmdir()


@contextlib.contextmanager
def report_folder_lock(folder: str | Path) -> Iterator[Path]:
    """Hold a report folder's lock for the duration of a ``with`` block.

    Parameters
    ----------
    folder : str or Path
        The ``--report`` folder (created if missing; removed again if it was created
        here and is empty at the end).

    Yields
    ------
    Path
        The lock file.

    Raises
    ------
    CampaignError
        Another campaign holds the folder (the message names its pid and host).
    """
    key = os.path.realpath(folder)
    with _GUARD:
        held = _HELD.get(key)
        if held is not None:
            held.count += 1
        else:
            held = _HELD[key] = _acquire(Path(folder))
    try:
        yield held.path
    finally:
        with _GUARD:
            held.count -= 1
            if held.count == 0:
                del _HELD[key]
                _release(held)


def holding_report_folder(argument: str) -> Callable[[F], F]:
    """Decorate a function so that it runs holding the lock of its report folder argument.

    Parameters
    ----------
    argument : str
        The name of the function's parameter that is the report folder.

    Returns
    -------
    callable
        The decorator.
    """

    def decorate(func: F) -> F:
        signature = inspect.signature(func)

        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            folder = signature.bind(*args, **kwargs).arguments[argument]
            with report_folder_lock(folder):
                return func(*args, **kwargs)

        return wrapper  # type: ignore[return-value]

    return decorate
