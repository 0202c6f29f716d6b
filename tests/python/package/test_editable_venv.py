"""The .venv that `make` installs wiretape into editable is a clean place to
run anyone's tests: pytest loads wiretape's plugin there without warning that
it cannot rewrite scikit-build-core's editable hook (issue 38)."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def test_pytest_in_this_venv_loads_the_plugin_without_a_rewrite_warning(tmp_path):
    (tmp_path / "test_user.py").write_text(textwrap.dedent("""
        def test_wiretapes_plugin_is_loaded(request):
            assert request.config.pluginmanager.hasplugin("wiretape")
    """))
    # A folder with no configuration of its own: what a user's project sees.
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    result = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider",
                             "-W", "error::pytest.PytestAssertRewriteWarning", "test_user.py"],
                            cwd=tmp_path, capture_output=True, text=True, timeout=120)
    output = result.stdout + result.stderr
    assert "PytestAssertRewriteWarning" not in output
    assert "_editable_skbc" not in output
    assert result.returncode == 0, output
    assert "1 passed" in output
