"""Every wheel in DIST installs where glibc 2.28 is (make wheel-smoke).

Usage: python tests/wheel_glibc.py DIST [MAX_GLIBC]   (default 2.28)

The wheel's platform tag must be manylinux_2_X with X no newer than
MAX_GLIBC, and no ELF file inside it (the extension, the preload shim, the
demo's programs) may ask for a newer glibc symbol version, or for the host's
libstdc++ (the C++ runtime is linked in statically). The tag alone is what
auditwheel derived; the symbol versions are what the loader will check.
Needs pyelftools, which auditwheel brings into the venv.
"""
from __future__ import annotations

import io
import re
import sys
import zipfile
from pathlib import Path

from elftools.elf.elffile import ELFFile
from elftools.elf.gnuversions import GNUVerNeedSection

TAG = re.compile(r"[-.]manylinux_(\d+)_(\d+)_")


def needed_versions(elf: ELFFile) -> dict[str, set[str]]:
    """Library name -> the symbol versions this ELF file needs from it."""
    needs: dict[str, set[str]] = {}
    for section in elf.iter_sections():
        if isinstance(section, GNUVerNeedSection):
            for library, versions in section.iter_versions():
                needs.setdefault(library.name, set()).update(v.name for v in versions)
    return needs


def version_tuple(name: str, prefix: str) -> tuple[int, ...]:
    return tuple(int(part) for part in name[len(prefix):].split("."))


def problems(wheel: Path, max_glibc: tuple[int, int]) -> list[str]:
    found: list[str] = []
    tag = TAG.search(wheel.name)
    if tag is None:
        return [f"{wheel.name}: no manylinux_X_Y tag"]
    if (int(tag[1]), int(tag[2])) > max_glibc:
        found.append(f"{wheel.name}: tagged manylinux_{tag[1]}_{tag[2]}, newer than "
                     f"{max_glibc[0]}.{max_glibc[1]}")
    elf_files = 0
    with zipfile.ZipFile(wheel) as archive:
        for member in archive.namelist():
            data = archive.read(member)
            if not data.startswith(b"\x7fELF"):
                continue
            elf_files += 1
            for library, versions in needed_versions(ELFFile(io.BytesIO(data))).items():
                if library.startswith("libstdc++"):
                    found.append(f"{wheel.name}: {member} needs the host's {library}")
                for version in versions:
                    if version.startswith("GLIBC_") and version[6:7].isdigit() and \
                            version_tuple(version, "GLIBC_")[:2] > max_glibc:
                        found.append(f"{wheel.name}: {member} needs {version} of {library}")
    if elf_files == 0:
        found.append(f"{wheel.name}: no ELF file inside")
    return found


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3):
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    dist = Path(argv[1])
    major, minor = (int(part) for part in (argv[2] if len(argv) == 3 else "2.28").split("."))
    wheels = sorted(dist.glob("wiretape-*.whl"))
    if not wheels:
        print(f"wheel_glibc: no wiretape wheel in {dist}", file=sys.stderr)
        return 1
    found = [line for wheel in wheels for line in problems(wheel, (major, minor))]
    for line in found:
        print(f"wheel_glibc: {line}", file=sys.stderr)
    if not found:
        print(f"wheel_glibc: {len(wheels)} wheel(s) install on glibc {major}.{minor}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
