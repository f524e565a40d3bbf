"""Limits on unpacking an FMU or an SSP archive (zip files): a total and a ratio.

An archive of a few MB can hold files of many GB (a file of zeros compresses about a
thousand times). Before anything of an archive is read or unpacked, :func:`check_archive`
adds up the sizes its zip directory declares and refuses, in one line, an archive that
would unpack to more than :func:`limits` allows:

- **total**: more than ``INS_COSIM_MAX_UNPACKED`` bytes (default :data:`MAX_UNPACKED`,
  1 GiB; ``"4 GiB"``, ``"500 MB"`` or a plain number of bytes);
- **ratio**: more than ``INS_COSIM_MAX_UNPACK_RATIO`` times the archive's own size
  (default :data:`MAX_RATIO`, 200), when it unpacks to more than :data:`RATIO_FLOOR`
  (16 MiB; a small archive is never refused for its ratio).

Declared sizes can lie, so :func:`extract_archive` also counts the bytes it writes and
stops (removing what it wrote) as soon as a file grows past its declared size or the
total past the limit; Python's :mod:`zipfile` additionally never returns more than a
member's declared size and checks its CRC. Member names with a drive, a leading slash, a
backslash or a ``..`` part are refused.
"""

from __future__ import annotations

import os
import re
import shutil
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from cosim.errors import FmuError

__all__ = [
    "MAX_RATIO",
    "MAX_UNPACKED",
    "RATIO_FLOOR",
    "check_archive",
    "extract_archive",
    "limits",
]

#: Default largest unpacked size of one archive [bytes] (``INS_COSIM_MAX_UNPACKED``).
MAX_UNPACKED = 2**30
#: Default largest ratio of unpacked to archive size (``INS_COSIM_MAX_UNPACK_RATIO``).
MAX_RATIO = 200.0
#: Unpacked sizes up to this [bytes] are never refused for their ratio.
RATIO_FLOOR = 16 * 2**20
TOTAL_VARIABLE = "INS_COSIM_MAX_UNPACKED"
RATIO_VARIABLE = "INS_COSIM_MAX_UNPACK_RATIO"
_CHUNK = 2**20
_SIZE = re.compile(r"^\s*([0-9.eE+]+)\s*([kKMGT]i?)?[bB]?\s*$")
_FACTORS = {"k": 1e3, "K": 1e3, "M": 1e6, "G": 1e9, "T": 1e12}


def _bytes(text: str) -> int:
    m = _SIZE.match(text)
    if m is None:
        raise ValueError(text)
    value, prefix = float(m.group(1)), m.group(2) or ""
    if prefix.endswith("i"):
        value *= 1024.0 ** ("KMGT".index(prefix[0].upper()) + 1)
    elif prefix:
        value *= _FACTORS[prefix]
    return int(value)


def limits() -> tuple[int, float]:
    """The limits in force: from the environment, else the defaults.

    Returns
    -------
    total : int
        Largest unpacked size [bytes].
    ratio : float
        Largest unpacked size / archive size.

    Raises
    ------
    FmuError
        An environment variable that is not a size or a positive number.
    """
    total, ratio = MAX_UNPACKED, MAX_RATIO
    text = os.environ.get(TOTAL_VARIABLE)
    if text:
        try:
            total = _bytes(text)
        except ValueError:
            raise FmuError(
                f"{TOTAL_VARIABLE}={text!r} is not a size; give bytes, e.g. '4 GiB' or 4e9"
            ) from None
    text = os.environ.get(RATIO_VARIABLE)
    if text:
        try:
            ratio = float(text)
        except ValueError:
            ratio = float("nan")
        if not ratio > 0:
            raise FmuError(f"{RATIO_VARIABLE}={text!r} is not a positive number, e.g. 500")
    return total, ratio


def _size(n: float) -> str:
    for unit, factor in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= factor:
            return f"{n / factor:.3g} {unit}"
    return f"{int(n)} bytes"


def check_archive(path: str | Path, what: str = "FMU") -> int:
    """Refuse an archive whose declared unpacked size exceeds the limits (reads no member).

    Parameters
    ----------
    path : str or Path
        The zip file (``.fmu``, ``.ssp``).
    what : str
        What it is, for the message (``"FMU"``, ``"SSP archive"``).

    Returns
    -------
    int
        The declared unpacked size [bytes].

    Raises
    ------
    FmuError
        Over a limit (the numbers and the environment variable that raises it), or not a
        zip file.
    """
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as zf:
            total = sum(info.file_size for info in zf.infolist())
    except (OSError, zipfile.BadZipFile) as exc:
        raise FmuError(f"{what} '{path}' is not a readable zip archive: {exc}") from None
    max_total, max_ratio = limits()
    packed = max(path.stat().st_size, 1)
    if total > max_total:
        raise FmuError(
            f"{what} '{path}' would unpack to {_size(total)} ({total} bytes declared), more "
            f"than the limit of {_size(max_total)}; if you trust it, raise the limit with the "
            f"environment variable {TOTAL_VARIABLE} (e.g. {TOTAL_VARIABLE}='{_raise(total)}')"
        )
    if total > RATIO_FLOOR and total > max_ratio * packed:
        raise FmuError(
            f"{what} '{path}' would unpack to {_size(total)} from {_size(packed)}, "
            f"{total / packed:.0f} times its size, more than the limit of {max_ratio:g} times; "
            f"if you trust it, raise the limit with the environment variable {RATIO_VARIABLE} "
            f"(e.g. {RATIO_VARIABLE}={10 ** len(str(int(total / packed)))})"
        )
    return total


def _raise(total: int) -> str:
    """A round size above ``total`` (for the message)."""
    gib = -(-total // 2**30)
    return f"{gib} GiB"


def extract_archive(path: str | Path, folder: str | Path, what: str = "FMU") -> None:
    """Unpack an archive into ``folder`` within the limits, counting the bytes written.

    Parameters
    ----------
    path : str or Path
        The zip file.
    folder : str or Path
        Where to unpack (created). On any failure whatever was written is removed.
    what : str
        What it is, for the message.

    Raises
    ------
    FmuError
        Over a limit (declared, or found while unpacking), an illegal member name, or a
        corrupt archive.
    """
    path, folder = Path(path), Path(folder)
    check_archive(path, what)
    max_total, _ratio = limits()
    written = 0
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                name = info.filename
                parts = PurePosixPath(name).parts
                if "\\" in name or ":" in name or name.startswith("/") or ".." in parts:
                    raise FmuError(
                        f"{what} '{path}' holds the illegal member name {name!r} (a drive, "
                        f"a leading slash, a backslash or '..')"
                    )
                target = folder.joinpath(*parts) if parts else folder
                if info.is_dir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                mine = 0
                with zf.open(info) as src, open(target, "wb") as dst:
                    while chunk := src.read(_CHUNK):
                        mine += len(chunk)
                        written += len(chunk)
                        if mine > info.file_size or written > max_total:
                            raise FmuError(
                                f"{what} '{path}': member {name!r} unpacks to more than its "
                                f"declared size ({info.file_size} bytes) or the total past "
                                f"the limit of {_size(max_total)}; refused"
                            )
                        dst.write(chunk)
    except FmuError:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    except (OSError, zipfile.BadZipFile, EOFError, zlib.error) as exc:
        shutil.rmtree(folder, ignore_errors=True)
        raise FmuError(f"cannot unpack {what} '{path}': {exc}") from None
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
