"""show's columns stay where they are however long the session runs: the
time and Δt columns are as wide as +99999.999999s."""

import re

from wiretape import _core, cli

ANSI = re.compile(r"\x1b\[[0-9;]*m")


def test_the_columns_do_not_move_when_times_pass_ten_and_a_hundred_seconds(tmp_path, capsys):
    session = tmp_path / "long.wtape"
    with _core.SessionWriter(str(session), port_type="loopback") as writer:
        for t_s in (0.5, 9.5, 12.25, 123.5, 4321.0):
            writer.write("tx", int(t_s * 1e9), b"PING\n")
    assert cli.main(["show", str(session), "--color", "never"]) == 0
    out = ANSI.sub("", capsys.readouterr().out)
    lines = [line for line in out.splitlines() if re.match(r"^[+-]\d", line)]
    assert len(lines) == 5
    assert len({line.index("tx") for line in lines}) == 1, "\n".join(lines)
    assert len({line.index("PING") for line in lines}) == 1, "\n".join(lines)
    heading = next(line for line in out.splitlines() if line.startswith("time"))
    assert heading.index("kind") == lines[0].index("tx")
