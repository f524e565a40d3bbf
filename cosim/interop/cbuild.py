"""Build a binary FMU from C sources with the system C compiler (no Python inside).

A *C FMU source folder* holds ``modelDescription.xml`` and one or more ``.c`` files
written against the FMI headers that ship with fmpy (``fmpy/c-code``: FMI 2.0
``fmi2Functions.h`` and FMI 3.0 ``fmi3Functions.h``). :func:`build_c_fmu` compiles
them into one shared library and zips it the way FMI lays an FMU out::

    modelDescription.xml
    binaries/<platform>/<modelIdentifier>.so     linux64 (FMI 2.0) or x86_64-linux (FMI 3.0)

The compiler and its flags are the project's one C build
(:func:`cosim.models.native.ccompile.compile_shared`, the same as the compiled
kernels'): ``$CC`` when set, else ``cc``, else ``gcc``, with ``-fvisibility=hidden`` among
the flags (only the FMI functions are exported, through the headers' ``FMI2_Export`` /
``FMI3_Export``). Linux only, as the rest of the test suite.

Command line (for building the vendor example by hand)::

    python -m cosim.interop.cbuild fmus/vendor_example fmus/build/VendorImu.fmu
"""

from __future__ import annotations

import os
import platform
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from pathlib import Path
from xml.etree import ElementTree

from cosim.errors import UserError
from cosim.models.native.ccompile import CompileError, compile_shared

__all__ = ["CBuildError", "build_c_fmu", "fmi_headers"]

#: Binary folder of an FMU for this machine, by FMI major version.
_PLATFORM = {"2": "linux64", "3": "x86_64-linux"}


class CBuildError(UserError):
    """A C FMU could not be built: no compiler, a compile error, or a bad source folder."""


def fmi_headers() -> Path:
    """The folder of the FMI 2.0 and 3.0 C headers shipped with fmpy.

    Returns
    -------
    Path
        ``.../site-packages/fmpy/c-code``.
    """
    import fmpy

    return Path(fmpy.__file__).resolve().parent / "c-code"


def _describe(xml_text: str, where: str) -> tuple[str, str]:
    """``(FMI major version, co-simulation model identifier)`` of a model description."""
    try:
        root = ElementTree.fromstring(xml_text)
    except ElementTree.ParseError as exc:
        raise CBuildError(f"{where}: not well-formed XML: {exc}") from exc
    version = root.get("fmiVersion", "")
    major = version.split(".", 1)[0]
    if major not in _PLATFORM:
        raise CBuildError(f"{where}: expected fmiVersion 2.0 or 3.0, got {version!r}")
    # the identifier of the co-simulation interface, else of the one the FMU has (the
    # tests build Scheduled-Execution-only and Model-Exchange-only FMUs on purpose)
    kinds = ("CoSimulation", "ScheduledExecution", "ModelExchange")
    cs = next((e for e in map(root.find, kinds) if e is not None), None)
    if cs is None or not cs.get("modelIdentifier"):
        raise CBuildError(
            f"{where}: expected a <CoSimulation modelIdentifier=...> element, got none"
        )
    return major, cs.get("modelIdentifier", "")


def build_c_fmu(
    source_dir: str | Path,
    out_path: str | Path,
    *,
    model_description: str | Path | None = None,
    defines: Sequence[str] = (),
) -> Path:
    """Compile the C sources of ``source_dir`` into a binary co-simulation FMU.

    Parameters
    ----------
    source_dir : str or Path
        Folder with ``modelDescription.xml`` and the ``*.c`` files (all compiled).
    out_path : str or Path
        The ``.fmu`` file to write (its folder is created).
    model_description : str or Path, optional
        Use this model description instead of ``source_dir/modelDescription.xml``: a
        path, or the XML text itself (a string starting with ``<``). The tests build
        deliberately wrong variants of an FMU this way, from the same C code.
    defines : sequence of str
        Preprocessor definitions passed as ``-D<define>`` (e.g. ``"VENDOR_IMU_GUID=..."``).

    Returns
    -------
    Path
        ``out_path``.

    Raises
    ------
    CBuildError
        No compiler, no sources, an unreadable model description, or a compile error
        (the compiler's messages are in the error).
    """
    source_dir = Path(source_dir)
    out_path = Path(out_path)
    sources = sorted(source_dir.glob("*.c"))
    if not sources:
        raise CBuildError(f"{source_dir}: expected C sources (*.c), got none")
    if model_description is None:
        md_file = source_dir / "modelDescription.xml"
        if not md_file.is_file():
            raise CBuildError(f"{source_dir}: expected a modelDescription.xml, got none")
        xml_text, where = md_file.read_text(encoding="utf-8"), str(md_file)
    elif isinstance(model_description, str) and model_description.lstrip().startswith("<"):
        xml_text, where = model_description, "model description (text)"
    else:
        xml_text = Path(model_description).read_text(encoding="utf-8")
        where = str(model_description)
    major, identifier = _describe(xml_text, where)
    if sys.platform != "linux" or platform.machine() not in ("x86_64", "AMD64"):
        raise CBuildError(
            f"building C FMUs is supported on x86_64 Linux, got {sys.platform} {platform.machine()}"
        )
    with tempfile.TemporaryDirectory(prefix="ins_cosim_cbuild_") as tmp:
        library = Path(tmp) / f"{identifier}.so"
        try:
            compile_shared(sources, library, include_dirs=[fmi_headers()], defines=defines)
        except CompileError as exc:
            raise CBuildError(f"{exc}{': ' + exc.log.strip() if exc.log else ''}") from exc
        out_path.parent.mkdir(parents=True, exist_ok=True)
        partial = out_path.with_name(out_path.name + ".part")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", xml_text)
            zf.write(library, f"binaries/{_PLATFORM[major]}/{identifier}.so")
        os.replace(partial, out_path)
    return out_path


def _main(argv: Sequence[str]) -> int:
    if len(argv) != 2:
        print("usage: python -m cosim.interop.cbuild SOURCE_DIR OUT.fmu", file=sys.stderr)
        return 2
    try:
        path = build_c_fmu(argv[0], argv[1])
    except CBuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    print(f"built {path}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(_main(sys.argv[1:]))
