"""The FMU entry script of ``cosim.interop.packaging``: what it does inside a host's interpreter."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

# A child Python host. It registers its probe with atexit *before* it loads the FMU, so
# the probe runs after every atexit handler the FMU registers (atexit is last in, first
# out) and just before the C exit handlers. The probe prints the control-block pointer of
# the library's static `pyState` shared_ptr (second word of the object), found from the
# library's load address in /proc/self/maps and the symbol's offset from `nm`.
PROBE = """
import atexit, ctypes, sys
from fmpy import simulate_fmu

fmu, name, offset = sys.argv[1], sys.argv[2], int(sys.argv[3], 16)

def probe():
    suffix = "/binaries/linux64/" + name + ".so"
    with open("/proc/self/maps") as maps:
        for line in maps:
            fields = line.split()
            path = " ".join(fields[5:]).removesuffix(" (deleted)")
            if path.endswith(suffix) and int(fields[2], 16) == 0:
                base = int(fields[0].split("-")[0], 16)
                break
        else:
            print("library not mapped", flush=True)
            return
    control = ctypes.c_void_p.from_address(base + offset + 8).value
    print("control block", hex(control or 0), flush=True)

atexit.register(probe)
simulate_fmu(fmu, stop_time=0.05)
simulate_fmu(fmu, stop_time=0.05)
"""


def _symbol_offset(library: Path, mangled: str) -> str:
    out = subprocess.run(["nm", str(library)], capture_output=True, text=True, check=True)
    for line in out.stdout.splitlines():
        fields = line.split()
        if fields[-1] == mangled:
            return fields[0]
    raise LookupError(f"{mangled} not in the symbol table of {library}")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ELF exit order is Linux's")
@pytest.mark.skipif(shutil.which("nm") is None, reason="needs nm (binutils, installed with gcc)")
def test_pythonfmu_state_is_released_before_the_faulty_exit_handlers(fmu_dir: Path) -> None:
    """pythonfmu 0.7 frees its static interpreter state in a C++ exit handler, then its ELF
    destructor decrements the freed control block (heap corruption at random). The entry
    script empties that shared_ptr from Python's atexit; if it did not, the probe would
    see a live control-block pointer when the C exit handlers start."""
    import pythonfmu

    library = Path(pythonfmu.__file__).parent / "resources/binaries/linux64/libpythonfmu-export.so"
    offset = _symbol_offset(library, "_ZN12_GLOBAL__N_17pyStateE")
    name = "GaussMarkov2"
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(fmu_dir / f"{name}.fmu"), name, offset],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "control block 0x0", proc.stdout
