"""The process ``edit_in_child()`` runs ``wiretape edit`` in
(``python -m wiretape.tools.edit_child``): it reads the request,
``(src, dst, options)`` pickled, on its stdin and writes its outcome,
``("result", EditResult)`` or ``("error", exception)`` pickled, on its
stdout. What else would go to stdout goes to stderr, so that nothing
mixes with the outcome."""

from __future__ import annotations

import os
import pickle
import sys

from .edit import edit


def main() -> int:
    outcome_pipe = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    src, dst, options = pickle.loads(sys.stdin.buffer.read())
    try:
        outcome = ("result", edit(src, dst, **options))
    except BaseException as error:  # every failure goes to the parent
        outcome = ("error", error)
    try:
        message = pickle.dumps(outcome)
    except Exception:
        message = pickle.dumps(("error", RuntimeError(str(outcome[1]))))
    with outcome_pipe:
        outcome_pipe.write(message)
    return 0


if __name__ == "__main__":
    sys.exit(main())
