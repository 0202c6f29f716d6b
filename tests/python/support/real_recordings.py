"""Where the real recordings the tests use live: Hokuyo scanners recorded
with flexiport in 2011, copied into ``tests/data/flexiport/`` with their
provenance and licence (README.md there), so that a fresh clone with nothing
beside it passes ``make test``.

A test that needs one and cannot find it fails, naming the path it looked in."""

import pathlib

import pytest

REPOSITORY = pathlib.Path(__file__).resolve().parents[3]
TEST_DATA_DIR = REPOSITORY / "tests" / "data"
FLEXIPORT_DIR = TEST_DATA_DIR / "flexiport"


def test_data_file(relative):
    """The path of `relative` inside tests/data; fails the test when it is not
    there."""
    path = TEST_DATA_DIR / relative
    if not path.exists():
        pytest.fail(f"test data is missing: {path} does not exist", pytrace=False)
    return path


def flexiport_log(name):
    """The flexiport recording `name` (``name.log`` stands for its
    ``name.logr`` + ``name.logw`` pair); fails the test when either is missing."""
    for suffix in ("logr", "logw"):
        test_data_file(f"flexiport/{name}.{suffix}")
    return FLEXIPORT_DIR / f"{name}.log"
