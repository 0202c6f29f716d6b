"""The table `make bench` prints at the end (bench/run.py): each figure of
bench/targets.py with its value, its target and whether it was met."""

import shutil

from targets import TARGETS  # bench/targets.py: key -> (target, better, what)


def print_table(results: dict, notes: dict, skipped: dict) -> None:
    rows = []
    for key, (target, better, what) in TARGETS.items():
        value = results.get(key)
        if value is None:
            verdict = "skipped"
        elif target is None or better == "info":
            verdict = ""
        elif better == "higher":
            verdict = "ok" if value >= target else "MISSED"
        else:
            verdict = "ok" if value <= target else "MISSED"
        goal = "" if target is None else (f"≥ {target}" if better == "higher" else f"≤ {target}")
        rows.append((key, "-" if value is None else f"{value:g}", goal, verdict, what))
    try:
        from rich.console import Console
        from rich.table import Table
    except ImportError:
        for row in rows:
            print("  ".join(f"{cell:<36}" if i == 0 else f"{cell:<10}" for i, cell in enumerate(row)))
    else:
        table = Table(title="wiretape benchmarks")
        for column in ("figure", "value", "target", "", "what"):
            table.add_column(column)
        for key, value, goal, verdict, what in rows:
            style = {"ok": "green", "MISSED": "red", "skipped": "yellow"}.get(verdict, "")
            table.add_row(key, value, goal, f"[{style}]{verdict}[/]" if style else verdict, what)
        Console(width=max(130, shutil.get_terminal_size().columns)).print(table)
    for key, note in notes.items():
        print(f"  {key}: {note}")
    for name, reason in skipped.items():
        print(f"  skipped {name}: {reason}")
