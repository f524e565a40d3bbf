"""Unpack limits on FMUs and SSP archives (issue 30, item 4, acceptance 4).

The archives are zip bombs made here without writing their unpacked bytes anywhere: a
file of zeros is deflated once per 16 MiB block with a full flush (each block then
compresses to the same bytes), the blocks are repeated, stored, and the zip headers are
patched to say "deflated, N bytes, this CRC" (the CRC of N zeros is combined from the
block's with zlib's ``crc32_combine`` algorithm). Deflate cannot compress more than about
1032 times, so a 3 GiB file is a 3 MB archive.
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from pathlib import Path

import pytest

from cosim.archives import check_archive, extract_archive, limits
from cosim.blocks import FmuHost
from cosim.errors import FmuError

TESTS = Path(__file__).resolve().parents[1]
BLOCK = 2**24
MD = (TESTS / "fixtures" / "abort2" / "modelDescription.xml").read_bytes()


def _times(mat: list[int], vec: int) -> int:
    s, i = 0, 0
    while vec:
        if vec & 1:
            s ^= mat[i]
        vec >>= 1
        i += 1
    return s


def _square(mat: list[int]) -> list[int]:
    return [_times(mat, mat[n]) for n in range(32)]


def crc32_combine(crc1: int, crc2: int, len2: int) -> int:
    """zlib's crc32_combine: the CRC-32 of A + B from those of A and B and len(B)."""
    odd = [0xEDB88320] + [1 << (n - 1) for n in range(1, 32)]
    even = _square(odd)
    odd = _square(even)
    while len2:
        even = _square(odd)
        if len2 & 1:
            crc1 = _times(even, crc1)
        len2 >>= 1
        if not len2:
            break
        odd = _square(even)
        if len2 & 1:
            crc1 = _times(odd, crc1)
        len2 >>= 1
    return crc1 ^ crc2


def zeros_crc(n_blocks: int) -> int:
    """CRC-32 of ``n_blocks * BLOCK`` zero bytes."""
    crc, length = zlib.crc32(bytes(BLOCK)), BLOCK
    total, total_len = 0, 0
    while n_blocks:
        if n_blocks & 1:
            total = crc32_combine(total, crc, length) if total_len else crc
            total_len += length
        crc, length = crc32_combine(crc, crc, length), 2 * length
        n_blocks >>= 1
    return total


def zip_bomb(path: Path, unpacked: int, declared: int | None = None, md: bool = True) -> Path:
    """A zip (FMU-shaped when ``md``) whose ``resources/big.bin`` unpacks to ``unpacked``
    zero bytes (a multiple of 16 MiB); ``declared`` is the size its headers state."""
    n = unpacked // BLOCK
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = c.compress(bytes(BLOCK)) + c.flush(zlib.Z_FULL_FLUSH)
    with zipfile.ZipFile(path, "w") as zf:
        if md:
            zf.writestr("modelDescription.xml", MD, zipfile.ZIP_DEFLATED)
        zf.writestr("resources/big.bin", block * n + b"\x03\x00", zipfile.ZIP_STORED)
        local = zf.getinfo("resources/big.bin").header_offset
    data = bytearray(path.read_bytes())
    crc, size = zeros_crc(n), unpacked if declared is None else declared
    struct.pack_into("<H", data, local + 8, 8)
    struct.pack_into("<II", data, local + 14, crc, len(block) * n + 2)
    struct.pack_into("<I", data, local + 22, size)
    central = data.rindex(b"PK\x01\x02")  # the last entry is big.bin
    struct.pack_into("<H", data, central + 10, 8)
    struct.pack_into("<I", data, central + 16, crc)
    struct.pack_into("<I", data, central + 24, size)
    path.write_bytes(bytes(data))
    return path


@pytest.fixture(scope="module")
def bomb(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 MB FMU whose resources unpack to 3 GiB."""
    return zip_bomb(tmp_path_factory.mktemp("bomb") / "Bomb.fmu", 3 * 2**30)


def test_the_bomb_is_what_it_says(bomb: Path) -> None:
    """The fixture is a real zip bomb: it declares 3 GiB, and its first MiB inflates."""
    assert 2e6 < bomb.stat().st_size < 6e6
    with zipfile.ZipFile(bomb) as zf:
        info = zf.getinfo("resources/big.bin")
        assert info.file_size == 3 * 2**30 and info.compress_type == zipfile.ZIP_DEFLATED
        with zf.open(info) as f:
            assert f.read(2**20) == bytes(2**20)


def test_a_3_gib_fmu_is_refused_in_one_line_within_a_second(tmp_path: Path, bomb: Path) -> None:
    """Acceptance 4 of issue 30 (in this process: the refusal's own time)."""
    t = time.perf_counter()
    with pytest.raises(FmuError) as info:
        FmuHost("imu", bomb)
    assert time.perf_counter() - t < 1.0
    text = str(info.value)
    assert "\n" not in text
    assert f"would unpack to 3 GiB ({3 * 2**30 + len(MD)} bytes declared)" in text
    assert "limit of 1 GiB" in text and "INS_COSIM_MAX_UNPACKED='4 GiB'" in text


def test_run_and_check_refuse_it_and_leave_nothing_on_disk(tmp_path: Path, bomb: Path) -> None:
    """Acceptance 4 of issue 30 (the commands: exit 3, one line, no folder left)."""
    scenario = tmp_path / "bomb.toml"
    scenario.write_text(f'[master]\nstep = "10 ms"\nstop = "1 s"\n\n[blocks.b]\nfmu = "{bomb}"\n')
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    for command in (["run", scenario, "--out", tmp_path / "out"], ["check", scenario]):
        res = subprocess.run(
            [sys.executable, "-m", "cosim.cli", *map(str, command)],
            capture_output=True,
            text=True,
            cwd=tmp_path,
            env=env,
            timeout=120,
        )
        assert res.returncode == 3, res.stderr
        (line,) = res.stderr.strip().splitlines()
        assert "would unpack to 3 GiB" in line and "INS_COSIM_MAX_UNPACKED" in line
    assert list(tmp.iterdir()) == []
    assert not (tmp_path / "out" / "results.csv").exists()


def test_the_ratio_limit_and_raising_the_limits(tmp_path: Path, monkeypatch) -> None:
    """64 MiB from about 64 KiB (ratio ~1000) is under the total but over the ratio."""
    small = zip_bomb(tmp_path / "Small.fmu", 64 * 2**20)
    with pytest.raises(FmuError, match=r"times its size, more than the limit of 200 times"):
        check_archive(small)
    monkeypatch.setenv("INS_COSIM_MAX_UNPACK_RATIO", "5000")
    assert check_archive(small) == 64 * 2**20 + len(MD)
    monkeypatch.setenv("INS_COSIM_MAX_UNPACKED", "32 MiB")
    with pytest.raises(FmuError, match="limit of 32 MiB"):
        check_archive(small)
    monkeypatch.setenv("INS_COSIM_MAX_UNPACKED", "lots")
    with pytest.raises(FmuError, match="INS_COSIM_MAX_UNPACKED='lots' is not a size"):
        limits()
    monkeypatch.setenv("INS_COSIM_MAX_UNPACKED", "4e9")
    assert limits() == (4_000_000_000, 5000.0)


def test_declared_sizes_that_lie_are_caught_while_unpacking(tmp_path: Path) -> None:
    """A member that says 1 MiB but inflates to 32 MiB: the check passes, unpacking
    stops at the declared size (and the CRC), and the folder is removed."""
    liar = zip_bomb(tmp_path / "Liar.fmu", 32 * 2**20, declared=2**20)
    assert check_archive(liar) == 2**20 + len(MD)
    folder = tmp_path / "unpacked"
    with pytest.raises(FmuError, match="Liar.fmu") as info:
        extract_archive(liar, folder)
    assert "\n" not in str(info.value)
    assert not folder.exists()
    # an honest archive unpacks, byte for byte
    honest = tmp_path / "honest.zip"
    with zipfile.ZipFile(honest, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("a/b.txt", "hello")
        zf.writestr("c/", "")
    extract_archive(honest, folder)
    assert (folder / "a" / "b.txt").read_text() == "hello" and (folder / "c").is_dir()


def test_an_ssp_bomb_is_refused(tmp_path: Path) -> None:
    from cosim.interop.ssp_import import load_ssp

    ssp = zip_bomb(tmp_path / "system.ssp", 3 * 2**30, md=False)
    with pytest.raises(FmuError, match=r"SSP archive .* would unpack to 3 GiB"):
        load_ssp(ssp)
