"""The ``wiretape`` console script (pyproject.toml): wiretape.cli's main(),
with the start-up's objects kept out of the garbage collector's way.

The command line's imports make tens of thousands of objects (modules,
classes, functions, their constants) that live until the process ends.
The collector would traverse them all in each full collection the imports
trigger, and again in the collections of the interpreter's exit: several
milliseconds of a short command such as ``replay --as -- CMD``
(replay_as_overhead_ratio, docs/benchmarks.md). So they are imported with
collection off, then frozen (``gc.freeze``: moved where no collection
looks); what the command itself makes is collected as before, and nothing
of the command's is frozen, so its objects are finalized at exit as before.

``main()`` called in-process (tests, ``python -m wiretape.cli``) is
wiretape.cli's own, without this.
"""

import gc


def main() -> int:
    """Runs the command line; returns the exit code."""
    gc.disable()
    try:
        from .cli.main import main as run_command_line
    finally:
        gc.freeze()
        gc.enable()
    return run_command_line()
