"""The end-of-run summary of the pytest plugin (DESIGN §11): how many
cassettes were replayed, recorded (and kept), appended to (new_episodes) or
run live, the cassettes in the tests' recording folders that no test names
any more, and the recordings in progress that a killed pytest left there
(removed)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, List, Set

import pytest

from .cassette import (cassette_file_name, default_cassette_dir, marker_settings,
                       remove_stale_recordings, source_file_of)


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


class CassetteSummary:
    """What the run did with cassettes (``note``) and which ones its test
    files name (``note_collected``)."""

    def __init__(self) -> None:
        self.counts: Dict[str, int] = {"replayed": 0, "recorded": 0, "appended": 0,
                                       "not kept": 0, "live": 0}
        self._folders: Set[Path] = set()
        self._named: Set[Path] = set()
        self._cassette_folders: Set[Path] = set()  # of the cassettes used, wherever

    def note_collected(self, item: pytest.Item) -> None:
        try:
            folder = default_cassette_dir(item)
            self._folders.add(folder)
            self._named.add(folder / cassette_file_name(item))
            cassette = marker_settings(item).get("cassette")
        except Exception:  # a test the plugin cannot name: nothing to claim
            return
        if cassette is not None:
            path = Path(os.fspath(cassette))
            if not path.is_absolute():
                path = source_file_of(item).parent / path
            self._named.add(path)

    def note(self, cassette, passed: bool) -> None:
        self._cassette_folders.add(cassette.path.parent)
        if cassette.live:
            self.counts["live"] += 1
        elif cassette.appending:
            # new_episodes: ports recorded onto a cassette replayed for the others
            self.counts["appended" if cassette.appended else
                        "not kept" if cassette.channels_to_record and not passed else
                        "replayed"] += 1
        elif cassette.recording:
            self.counts["recorded" if passed and cassette.path.exists() else "not kept"] += 1
        else:
            self.counts["replayed"] += 1

    def orphans(self) -> List[Path]:
        named = {os.path.realpath(path) for path in self._named}
        found = []
        for folder in sorted(self._folders):
            if folder.is_dir():
                found += [path for path in sorted(folder.glob("*.wtape"))
                          if os.path.realpath(path) not in named]
        return found

    def stale_recordings(self) -> List[Path]:
        """Removes and returns the recordings in progress (``NAME.recording-PID``)
        of processes that are gone, in the folders of the cassettes."""
        removed = []
        for folder in sorted(self._folders | self._cassette_folders):
            removed += remove_stale_recordings(folder)
        return removed

    def lines(self) -> List[str]:
        """Nothing when no test used a cassette, none is orphaned and no
        stale recording was removed."""
        used = sum(self.counts.values())
        orphans = self.orphans()
        stale = self.stale_recordings()
        if not used and not orphans and not stale:
            return []
        lines = []
        if used:
            parts = [f"{count} {what}" for what, count in self.counts.items() if count]
            lines.append(f"{_plural(used, 'cassette')}: " + ", ".join(parts)
                         + ("  (not kept: the test failed while recording)"
                            if self.counts["not kept"] else ""))
        if orphans:
            lines.append(f"{_plural(len(orphans), 'cassette')} no collected test names "
                         "(a renamed or removed test?):")
            lines += [f"    {path}" for path in orphans]
        if stale:
            lines.append(f"removed {_plural(len(stale), 'recording')} left in progress by a "
                         "pytest that was killed (its process is gone):")
            lines += [f"    {path}" for path in stale]
        return lines
