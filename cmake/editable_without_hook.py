"""Drops the import hook from .venv's editable install of wiretape.

scikit-build-core's editable install (inplace mode, pyproject.toml) puts
python/ on sys.path with a .pth line, which is all a prebuilt package in its
source tree needs, and also a hook module that the .pth imports at every
start of Python. wiretape's distribution has a pytest11 entry point, so pytest
marks every module of it for assertion rewriting, finds the hook already
imported, and warns (PytestAssertRewriteWarning: Module already imported so
cannot be rewritten: _editable_skbc_wiretape) in every pytest run in the
.venv, in any project. pytest skips only setuptools' ``__editable__``
finders (scikit-build-core #1327). Without the hook the warning has no cause.

Usage: python editable_without_hook.py  (in the .venv's own interpreter)
"""

from __future__ import annotations

import csv
import io
import os
import sysconfig

HOOK = "_editable_skbc_wiretape"


def main() -> int:
    site = sysconfig.get_paths()["purelib"]
    pth = os.path.join(site, f"{HOOK}.pth")
    if not os.path.exists(pth):
        return 0
    with open(pth, encoding="utf-8") as stream:
        lines = [line for line in stream.read().splitlines()
                 if line.strip() and not line.startswith("import ")]
    if not lines:
        raise SystemExit(f"{pth}: no path line to keep: not an inplace editable install")
    with open(pth, "w", encoding="utf-8") as stream:
        stream.write("\n".join(lines) + "\n")
    removed = {f"{HOOK}.py", f"__pycache__/{HOOK}.cpython-"}
    for name in os.listdir(site):
        if name.startswith("wiretape-") and name.endswith(".dist-info"):
            record = os.path.join(site, name, "RECORD")
            with open(record, encoding="utf-8", newline="") as stream:
                rows = list(csv.reader(stream))
            kept = [row for row in rows if not any(row[0].startswith(prefix) for prefix in removed)]
            text = io.StringIO()
            csv.writer(text, lineterminator="\n").writerows(kept)
            with open(record, "w", encoding="utf-8", newline="") as stream:
                stream.write(text.getvalue())
    for path in (os.path.join(site, f"{HOOK}.py"),):
        if os.path.exists(path):
            os.unlink(path)
    cache = os.path.join(site, "__pycache__")
    if os.path.isdir(cache):
        for name in os.listdir(cache):
            if name.startswith(f"{HOOK}."):
                os.unlink(os.path.join(cache, name))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
