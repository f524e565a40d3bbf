"""The folders FMUs are unpacked into, shared by the instances of one FMU in a process.

Unpacking every instance into a new temporary folder loaded its shared library again
from a new path on every run (a library that stays in memory is never found again), so
repeated runs in one process kept mapping libraries and growing. Here one FMU content
has one folder per process, removed with its last instance; folders of processes that
were killed are swept by the next process that unpacks an FMU.
"""

from __future__ import annotations

import atexit
import os
import re
import shutil
import sys
import tempfile
import threading
from pathlib import Path

from cosim.archives import extract_archive
from cosim.errors import FmuError


class UnpackedFolders:
    """The folders FMUs are unpacked into: one per FMU content and process, shared.

    Every instance of one FMU file (same SHA-256) in a process uses the same folder,
    ``<tmp>/ins_cosim_<pid>_<model>_<sha256[:16]>``, unpacked when the first instance is made
    and removed when the last one is freed (:meth:`FmuHost.terminate`, or a failed
    instantiation). Its path is the same for every run of the process, so the FMU's shared
    library is loaded from one path: a library that stays in memory after it is freed
    (pythonfmu's binaries are pinned, see :mod:`cosim.interop.packaging`) is found again
    instead of being loaded once more from a new folder per run, and repeated runs keep
    memory and time per run flat. Folders left behind by a process that was killed
    (``SIGKILL``, a crashed worker) are removed the first time a process unpacks an FMU;
    what is still in use at exit is removed then.
    """

    def __init__(self) -> None:
        self._users: dict[str, int] = {}
        self._lock = threading.Lock()
        self._swept = False

    @staticmethod
    def root() -> Path:
        """The temporary directory the folders are made in (:func:`tempfile.gettempdir`)."""
        return Path(tempfile.gettempdir())

    def acquire(self, fmu: Path, sha256: str) -> str:
        """The unpacked folder of an FMU, unpacked now if no instance uses it yet.

        Parameters
        ----------
        fmu : Path
            The ``.fmu`` file.
        sha256 : str
            Its hash (:func:`file_sha256`), which names the folder.

        Returns
        -------
        str
            The folder (to pass to fmpy as ``unzipDirectory``); give it back with
            :meth:`release`.

        Raises
        ------
        FmuError
            The archive cannot be unpacked (corrupt zip, illegal member paths, over the
            unpack limits of :mod:`cosim.archives`).
        """
        stem = re.sub(r"[^\w.-]", "_", Path(fmu).stem)[:40]
        folder = str(self.root() / f"{PREFIX}{os.getpid()}_{stem}_{sha256[:16]}")
        with self._lock:
            if not self._swept:
                self._swept = True
                self.sweep()
            if self._users.get(folder, 0) == 0:
                shutil.rmtree(folder, ignore_errors=True)  # a dead process with our pid
                try:  # within the unpack limits (cosim.archives), counted while written
                    extract_archive(fmu, folder)
                except FmuError:
                    raise
                except Exception as exc:
                    shutil.rmtree(folder, ignore_errors=True)
                    raise FmuError(f"cannot unpack FMU '{fmu}': {exc}") from exc
                except BaseException:  # Ctrl-C while unpacking: not yet ours to remove at exit
                    shutil.rmtree(folder, ignore_errors=True)
                    raise
            self._users[folder] = self._users.get(folder, 0) + 1
        return folder

    def release(self, folder: str) -> None:
        """One instance less uses ``folder``; the last one removes it.

        Parameters
        ----------
        folder : str
            A folder returned by :meth:`acquire`.
        """
        with self._lock:
            left = self._users.get(folder, 0) - 1
            if left > 0:
                self._users[folder] = left
                return
            self._users.pop(folder, None)
        resources = os.path.join(folder, "resources")
        if resources in sys.path:  # put there by pythonfmu when it instantiated
            sys.path[:] = [p for p in sys.path if p != resources]
        shutil.rmtree(folder, ignore_errors=True)

    def in_use(self) -> list[str]:
        """The folders instances of this process use now.

        Returns
        -------
        list of str
            Paths, in the order they were unpacked.
        """
        with self._lock:
            return list(self._users)

    def sweep(self) -> list[str]:
        """Remove the folders of processes that no longer run.

        Returns
        -------
        list of str
            The folders removed.
        """
        removed = []
        for folder in self.root().glob(f"{PREFIX}*_*"):
            pid = folder.name[len(PREFIX) :].split("_", 1)[0]
            if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(str(folder))
        return removed

    def remove_all(self) -> None:
        """Remove every folder of this process (at exit: what a failure left in use)."""
        with self._lock:
            folders, self._users = list(self._users), {}
        for folder in folders:
            shutil.rmtree(folder, ignore_errors=True)


#: How the names of the unpacked folders begin (:class:`UnpackedFolders`).
PREFIX = "ins_cosim_"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def drop_repeated_path_entries() -> None:
    """Keep the first of repeated ``sys.path`` entries (after an FMU is instantiated).

    pythonfmu puts an instance's resources folder at the front of ``sys.path`` each time it
    instantiates; with one folder per FMU (:class:`UnpackedFolders`) that is the same entry
    again and again, and a path that grows by one entry per run slows every import.
    """
    seen: set[str] = set()
    kept = []
    for entry in sys.path:
        if entry not in seen:
            seen.add(entry)
            kept.append(entry)
    if len(kept) != len(sys.path):
        sys.path[:] = kept


#: The process's unpacked FMU folders.
unpacked_folders = UnpackedFolders()
atexit.register(unpacked_folders.remove_all)
