"""``wiretape://PATH?KEY=VALUE&...``: a pyserial port replaying a session file.

The query's keys are the replay keys of ``type=replay`` (docs/options.md;
``wiretape.options.replay_keys()``); an unknown key is a ``SerialException`` that names it
and lists the valid ones.
"""

from .. import _core
from ._common import PortSerial, parse_url

SCHEME = "wiretape"


def replay_options(url):
    """The wiretape option string a ``wiretape://`` URL stands for."""
    path, pairs = parse_url(url, SCHEME)
    return _core.option_string([("type", "replay"), ("file", path)] + pairs)


class Serial(PortSerial):
    """pyserial's Serial, replaying the session named by the URL."""

    def _open_wiretape_port(self, url):
        return _core.open_port(replay_options(url))
