"""The fenced code blocks of README.md and docs/*.md, and the manifest of
the blocks that cannot run here (tests/python/docs/examples.toml).

A block is known by its file and its first line (not its line number, so
that editing the text above it does not unlist it)."""

import dataclasses
import pathlib
import re
import tomllib

REPO = pathlib.Path(__file__).resolve().parents[3]
MANIFEST = REPO / "tests" / "python" / "docs" / "examples.toml"

_FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>```+|~~~+)\s*(?P<lang>[^\s`]*)")


@dataclasses.dataclass(frozen=True)
class Block:
    file: str  # relative to the repository, with "/"
    line: int  # the line of the opening fence, 1-based
    lang: str  # "" when the block names none
    text: str

    @property
    def first_line(self) -> str:
        for line in self.text.splitlines():
            if line.strip():
                return line.strip()
        return ""

    @property
    def key(self):
        return (self.file, self.first_line)

    @property
    def id(self) -> str:
        return f"{self.file}:{self.line}"


def documentation_files():
    files = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")),
             REPO / "examples" / "hokuyo" / "README.md"]
    return [f for f in files if f.exists()]


def blocks_of(path: pathlib.Path):
    relative = path.relative_to(REPO).as_posix()
    lines = path.read_text(encoding="utf-8").split("\n")
    index = 0
    while index < len(lines):
        opening = _FENCE.match(lines[index])
        if not opening:
            index += 1
            continue
        fence, indent = opening["fence"], len(opening["indent"])
        end = index + 1
        while end < len(lines) and not lines[end].strip().startswith(fence):
            end += 1
        if end == len(lines):
            raise ValueError(f"{relative}:{index + 1}: code block never closed")
        body = [line[indent:] if not line[:indent].strip() else line.lstrip()
                for line in lines[index + 1:end]]
        yield Block(relative, index + 1, opening["lang"].lower(), "\n".join(body) + "\n")
        index = end + 1


def all_blocks():
    return [block for path in documentation_files() for block in blocks_of(path)]


def load_manifest():
    """{(file, first line): reason} of the blocks that are not run."""
    with MANIFEST.open("rb") as stream:
        table = tomllib.load(stream)
    listed = {}
    for file, entries in table.items():
        for first_line, reason in entries.items():
            if not reason.strip():
                raise ValueError(f"{MANIFEST}: [{file}] {first_line!r} gives no reason")
            listed[(file, first_line)] = reason
    return listed


# Lines that vary from run to run, masked on both sides before comparing.
_VARYING = [
    (re.compile(r"/dev/pts/\d+"), "/dev/pts/N"),
    (re.compile(r"/tmp/\S*"), "/tmp/..."),
    (re.compile(r"\b\d{4}-\d\d-\d\dT[\d:.]+Z?"), "TIME"),
    (re.compile(r"\b\d+\.\d+\s*(s|ms|µs|us)\b"), "DURATION"),
    (re.compile(r"\bpid \d+"), "pid N"),
    (re.compile(r"[ \t]+"), " "),
]


def masked(text: str) -> str:
    out = []
    for line in text.splitlines():
        for pattern, replacement in _VARYING:
            line = pattern.sub(replacement, line)
        if line.strip():
            out.append(line.strip())
    return "\n".join(out)
