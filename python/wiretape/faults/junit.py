"""A campaign as JUnit XML (``--junit FILE``), the report every CI system
reads: one ``<testcase>`` per run, named ``KIND@WHERE``; a crash or a hang is
a ``<failure>`` whose text starts with the line that reproduces it."""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ElementTree
from typing import Iterable, Optional

from .report import Campaign, Run, write_whole

# XML 1.0 has no way to write these, even escaped: a driver's output may hold them.
_NOT_XML = re.compile("[^\t\n\r\u0020-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")

#: The outcomes a CI should show as failed (as the exit status 1 counts them).
FAILED_OUTCOMES = ("crash", "hang")


def _text(value: str) -> str:
    return _NOT_XML.sub("\ufffd", value)


def _suite_name(result: Campaign, tool: str) -> str:
    name = f"{tool} {os.path.basename(result.session)}"
    return f"{name} shard {result.shard}" if result.shard else name


def campaign_xml(result: Campaign, tool: str = "wiretape faults",
                 output_lines: int = 20) -> ElementTree.Element:
    """The ``<testsuites>`` document of one campaign (or of one shard)."""
    runs = list(result.runs)
    failures = sum(run.outcome in FAILED_OUTCOMES for run in runs)
    seconds = sum(run.seconds for run in runs)
    suites = ElementTree.Element("testsuites", name=_text(tool), tests=str(len(runs)),
                                 failures=str(failures), errors="0", time=f"{seconds:.3f}")
    suite = ElementTree.SubElement(suites, "testsuite", name=_text(_suite_name(result, tool)),
                                   tests=str(len(runs)), failures=str(failures), errors="0",
                                   skipped="0", time=f"{seconds:.3f}")
    properties = ElementTree.SubElement(suite, "properties")
    facts = [("session", result.session), ("session_sha256", result.session_sha256),
             ("seed", str(result.seed)), ("speed", f"{result.speed:g}")]
    if result.shard:
        facts.append(("shard", str(result.shard)))
        if result.shard.engine:
            facts.append(("shard_from", result.shard.engine))
    if result.interrupted:
        facts.append(("interrupted", f"after {len(runs)} of {result.planned} runs"))
    for name, value in facts:
        ElementTree.SubElement(properties, "property", name=name, value=_text(value))
    classname = _text(f"{tool.replace(' ', '.')}.{os.path.basename(result.session)}")
    for run in runs:
        _testcase(suite, run, classname, output_lines)
    return suites


def _testcase(suite: ElementTree.Element, run: Run, classname: str, output_lines: int) -> None:
    case = ElementTree.SubElement(suite, "testcase", classname=classname,
                                  name=_text(run.spec), time=f"{run.seconds:.3f}")
    if run.outcome in FAILED_OUTCOMES:
        status = "" if run.exit is None else f" (exit {run.exit})"
        failure = ElementTree.SubElement(case, "failure", type=run.outcome,
                                         message=_text(f"{run.outcome} {run.spec}{status}"))
        tail = run.output.splitlines()[-output_lines:] if run.output else []
        failure.text = _text("\n".join([f"reproduce: {run.repro}"] + tail))
    elif run.outcome == "error":
        # The driver saw the fault and said so: a right answer, shown as a pass.
        output = ElementTree.SubElement(case, "system-out")
        output.text = _text(f"the driver reported an error (exit {run.exit})")


def write_junit(result: Campaign, path: str, tool: str = "wiretape faults") -> None:
    """Writes the campaign's JUnit XML whole or not at all."""
    document = ElementTree.ElementTree(campaign_xml(result, tool))
    ElementTree.indent(document)

    def write(output) -> None:
        output.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        document.write(output, encoding="unicode")
        output.write("\n")
    write_whole(path, write, suffix=".xml")
