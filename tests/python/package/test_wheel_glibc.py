"""tests/wheel_glibc.py, the check make wheel runs on its wheels, on wheels
made here from ELF files whose symbol versions are known."""
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("elftools", reason="pyelftools is installed by make (.venv)")
from elftools.elf.elffile import ELFFile  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
CHECK = ROOT / "tests" / "wheel_glibc.py"
sys.path.insert(0, str(CHECK.parent))
import wheel_glibc  # noqa: E402


def newest_glibc(path: Path) -> tuple:
    with path.open("rb") as stream:
        needs = wheel_glibc.needed_versions(ELFFile(stream))
    return max(wheel_glibc.version_tuple(v, "GLIBC_") for v in needs.get("libc.so.6", ())
               if v[6:7].isdigit())


def a_wheel(directory: Path, tag: str, elf: Path) -> Path:
    wheel = directory / f"wiretape-0.1.0-cp311-cp311-{tag}.whl"
    with zipfile.ZipFile(wheel, "w") as archive:
        archive.write(elf, "wiretape/_core.so")
        archive.writestr("wiretape/__init__.py", "")
    return wheel


def run(dist: Path, max_glibc: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(CHECK), str(dist), max_glibc],
                          capture_output=True, text=True, timeout=60)


def test_a_wheel_whose_symbols_fit_passes_and_one_step_older_fails(tmp_path):
    # The Python running the tests is an ELF file of this machine: its newest
    # glibc symbol version decides where the check must draw the line.
    elf = Path(sys.executable).resolve()
    newest = newest_glibc(elf)
    a_wheel(tmp_path, "manylinux_2_17_x86_64", elf)
    fits = run(tmp_path, f"{newest[0]}.{newest[1]}")
    assert fits.returncode == 0, fits.stderr
    assert "1 wheel(s) install" in fits.stdout
    older = run(tmp_path, f"{newest[0]}.{newest[1] - 1}")
    assert older.returncode == 1
    assert f"wiretape/_core.so needs GLIBC_{newest[0]}.{newest[1]}" in older.stderr


def test_a_tag_newer_than_the_limit_fails_naming_it(tmp_path):
    a_wheel(tmp_path, "manylinux2014_x86_64.manylinux_2_35_x86_64", Path(sys.executable).resolve())
    result = run(tmp_path, "9.0")  # the symbols fit; only the tag is too new
    assert result.returncode == 0
    result = run(tmp_path, "2.28")
    assert result.returncode == 1
    assert "tagged manylinux_2_35, newer than 2.28" in result.stderr


def test_a_wheel_needing_the_hosts_libstdcxx_fails(tmp_path):
    # The extension make builds with the host's gcc links its libstdc++.
    import wiretape._core as core

    extension = Path(core.__file__)
    with extension.open("rb") as stream:
        if not any(name.startswith("libstdc++")
                   for name in wheel_glibc.needed_versions(ELFFile(stream))):
            pytest.skip(f"{extension.name} does not link the host's libstdc++")
    a_wheel(tmp_path, "manylinux_2_17_x86_64", extension)
    result = run(tmp_path, "9.0")
    assert result.returncode == 1
    assert "wiretape/_core.so needs the host's libstdc++" in result.stderr


def test_no_wheel_is_an_error(tmp_path):
    result = run(tmp_path, "2.28")
    assert result.returncode == 1
    assert "no wiretape wheel in" in result.stderr
