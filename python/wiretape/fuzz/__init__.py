"""``wiretape fuzz`` (DESIGN §27, docs/fuzzing.md "Unmodified programs"):
plans over a recording run as replays to a program, and what breaks it
written as findings that ``wiretape replay`` plays back.

One job per module: ``search`` (the runs, minimization, the findings
written), ``findings`` (a run's verdict and signature, index.json, plan
files), ``coverage`` (AFL++'s map: instrumented programs, hit-count
buckets). In-process fuzzing is :mod:`wiretape.fuzzing`.
"""

from .findings import INDEX, Finding, PlanFileError, finding_kind, read_index, read_plan_file
from .search import (CORPUS_DIR, DEFAULT_RUNS, Search, Target, mutated_plan, random_plan,
                     replay_findings, search)

__all__ = ["CORPUS_DIR", "INDEX", "DEFAULT_RUNS", "Finding", "PlanFileError", "Search", "Target",
           "finding_kind", "mutated_plan", "random_plan", "read_index", "read_plan_file", "replay_findings",
           "search"]
