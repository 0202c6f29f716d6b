"""Where the shared test data lives: real recordings made on the hardware,
kept beside the repository rather than in it. One place reads the setting:

``WIRETAPE_SHARED_DATA_DIR`` (default: ``<repository>/../shared/data``, where
a CI checkout finds ``shared/`` beside the clone).

The data is part of the repository's test set-up: a test that needs it and
cannot find it fails, naming the path it looked in."""

import os
import pathlib

import pytest

REPOSITORY = pathlib.Path(__file__).resolve().parents[2]
SHARED_DATA_DIR = pathlib.Path(
    os.environ.get("WIRETAPE_SHARED_DATA_DIR") or REPOSITORY.parent / "shared" / "data")
FLEXIPORT_DIR = SHARED_DATA_DIR / "flexiport"


def _missing(path):
    pytest.fail(f"the shared test data is missing: {path} does not exist (set "
                f"WIRETAPE_SHARED_DATA_DIR to the folder holding flexiport/...; "
                f"default {REPOSITORY.parent / 'shared' / 'data'})", pytrace=False)


def shared_data_file(relative):
    """The path of `relative` inside the shared data; fails the test when it
    is not there."""
    path = SHARED_DATA_DIR / relative
    if not path.exists():
        _missing(path)
    return path


def flexiport_log(name):
    """The flexiport recording `name` (``name.log`` stands for its
    ``name.logr`` + ``name.logw`` pair); fails the test when either is missing."""
    for suffix in ("logr", "logw"):
        shared_data_file(f"flexiport/{name}.{suffix}")
    return FLEXIPORT_DIR / f"{name}.log"
