"""The real recordings copied into tests/data/flexiport are the published
bytes, untouched: each file's size and SHA-256 match its README's table."""

import hashlib
import re

from real_recordings import FLEXIPORT_DIR


def readme_table():
    text = (FLEXIPORT_DIR / "README.md").read_text()
    rows = re.findall(r"^\| `([^`]+)` \| (\d+) \| `([0-9a-f]{64})` \|$", text, re.MULTILINE)
    return {name: (int(size), digest) for name, size, digest in rows}


def test_every_recording_is_listed_with_its_provenance():
    text = (FLEXIPORT_DIR / "README.md").read_text()
    assert "hokuyoaist" in text and "LGPL" in text
    files = {path.name for path in FLEXIPORT_DIR.iterdir() if path.suffix in (".logr", ".logw")}
    assert files == set(readme_table()) == {
        "urg04lx_2011.logr", "urg04lx_2011.logw", "utm30lx_2011.logr", "utm30lx_2011.logw"}


def test_every_recording_has_its_published_bytes():
    for name, (size, digest) in readme_table().items():
        data = (FLEXIPORT_DIR / name).read_bytes()
        assert len(data) == size, name
        assert hashlib.sha256(data).hexdigest() == digest, name
