"""python/wiretape/_core.pyi is what nanobind's stubgen makes of the
extension: regenerated here and compared with the checked-in file."""

import difflib
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[3]
CHECKED_IN = ROOT / "python" / "wiretape" / "_core.pyi"


def test_the_checked_in_stub_is_what_stubgen_generates(tmp_path):
    generated = tmp_path / "_core.pyi"
    result = subprocess.run(
        [sys.executable, "-m", "nanobind.stubgen", "-m", "wiretape._core", "-o", str(generated)],
        capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"stubgen failed:\n{result.stdout}{result.stderr}"
    want, got = CHECKED_IN.read_text(), generated.read_text()
    if want != got:
        difference = "".join(list(difflib.unified_diff(
            want.splitlines(True), got.splitlines(True),
            "python/wiretape/_core.pyi (checked in)", "generated"))[:60])
        raise AssertionError(f"{CHECKED_IN} differs from the bindings: run make stubs\n"
                             f"{difference}")
