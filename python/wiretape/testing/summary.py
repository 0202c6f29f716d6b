"""The end-of-run summary of the pytest plugin (DESIGN §11): how many
cassettes were replayed, recorded (and kept), appended to (new_episodes) or
run live (a cassette shared by several tests counted once), the cassettes
that a passing test left partly unread, the cassettes in the tests'
recording folders that no test names any more, and the recordings in
progress that a killed pytest left there (removed)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Dict, List, Set

import pytest

from .cassette import (cassette_file_name, default_cassette_dir, marker_settings,
                       remove_stale_recordings, source_file_of)


def _plural(count: int, word: str) -> str:
    return f"{count} {word}" + ("" if count == 1 else "s")


# What a cassette's tests did with it, in the summary's order.
OUTCOMES = ("replayed", "recorded", "appended", "not kept", "live")
# A cassette that several tests share is counted once, under the strongest
# thing one of them did to it.
STRONGEST_FIRST = ("recorded", "appended", "not kept", "replayed", "live")


class CassetteSummary:
    """What the run did with cassettes (``note``) and which ones its test
    files name (``note_collected``)."""

    def __init__(self) -> None:
        self._outcomes: Dict[str, str] = {}  # cassette (real path) -> outcome
        self._left_unused: Dict[str, Dict[str, None]] = {}  # cassette -> what its tests left
        self._folders: Set[Path] = set()
        self._named: Set[Path] = set()
        self._cassette_folders: Set[Path] = set()  # of the cassettes used, wherever
        self._kept: List[str] = []  # the replay commands of failing live tests' recordings

    @property
    def counts(self) -> Dict[str, int]:
        """Cassettes by outcome, each counted once."""
        counts = {outcome: 0 for outcome in OUTCOMES}
        for outcome in self._outcomes.values():
            counts[outcome] += 1
        return counts

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
        recording = getattr(cassette, "live_recording", None)
        if recording is not None and recording.was_kept:
            from .live import replay_command

            self._kept.append(replay_command(cassette.item.nodeid, recording.kept))
        self._cassette_folders.add(cassette.path.parent)
        if cassette.live:
            outcome = "live"
        elif cassette.appending:
            # new_episodes: ports recorded onto a cassette replayed for the others
            outcome = ("appended" if cassette.appended else
                       "not kept" if cassette.channels_to_record and not passed else
                       "replayed")
        elif cassette.recording:
            outcome = "recorded" if passed and cassette.path.exists() else "not kept"
        else:
            outcome = "replayed"
        # The device of a live test is no cassette: each test is its own.
        key = (f"live {cassette.item.nodeid}" if cassette.live
               else os.path.realpath(cassette.path))
        known = self._outcomes.get(key)
        if known is None or STRONGEST_FIRST.index(outcome) < STRONGEST_FIRST.index(known):
            self._outcomes[key] = outcome
        if cassette.left_unused and passed and not cassette.recording:
            left = self._left_unused.setdefault(str(cassette.path), {})
            left.update(dict.fromkeys(cassette.left_unused))

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
        counts = self.counts
        used = sum(counts.values())
        orphans = self.orphans()
        stale = self.stale_recordings()
        if not used and not orphans and not stale and not self._kept:
            return []
        lines = []
        if used:
            parts = [f"{count} {what}" for what, count in counts.items() if count]
            lines.append(f"{_plural(used, 'cassette')}: " + ", ".join(parts)
                         + ("  (not kept: the test failed while recording)"
                            if counts["not kept"] else ""))
        if self._left_unused:
            lines.append(f"{_plural(len(self._left_unused), 'cassette')} left partly unread "
                         "by a passing test (replay key unused=error makes it a failure; "
                         "docs/testing.md):")
            for path, reports in sorted(self._left_unused.items()):
                lines.append(f"    {path}: " + "; ".join(reports))
        if orphans:
            lines.append(f"{_plural(len(orphans), 'cassette')} no collected test names "
                         "(a renamed or removed test?):")
            lines += [f"    {path}" for path in orphans]
        if self._kept:
            lines.append(f"{_plural(len(self._kept), 'failing live test')} kept "
                         "its recording; replay each with:")
            lines += [f"    {command}" for command in self._kept]
        if stale:
            lines.append(f"removed {_plural(len(stale), 'recording')} left in progress by a "
                         "pytest that was killed (its process is gone):")
            lines += [f"    {path}" for path in stale]
        return lines
