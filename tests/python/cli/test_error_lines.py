"""A newcomer's mistakes (issue 38): each is one line on stderr, exit 2 (3
for a host that does not exist, as for a device path that does not),
naming the mistake itself and, for a typo, what was meant; never a usage
block before it."""

from pathlib import Path

import pytest

from wiretape import cli

SESSION = str(Path(__file__).resolve().parents[3] / "examples" / "hokuyo" / "recordings"
              / "urg04lx_gd.wtape")


def run(capsys, argv):
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.err


CASES = [
    # (argv, exit code, the whole line, or a list of what it holds)
    (["replay", SESSION, "--pty", "{tmp}/tty", "--timnig", "none"], 2,
     "wiretape replay: error: unknown option '--timnig' (did you mean --timing?)"),
    (["replay", SESSION, "--pty", "{tmp}/tty", "--timing", "fast"], 2,
     ["wiretape replay: error: argument --timing: invalid choice: 'fast'", "causal"]),
    (["record", "--device", "type=loopback", "--pty", "{tmp}/tty"], 2,
     "wiretape record: error: the following arguments are required: -o/--output "
     "(see wiretape record --help)"),
    (["record", "--device", "type=loopback", "--pty", "{tmp}/tty", "--ouput", "{tmp}/out.wtape"],
     2, "wiretape record: error: unknown option '--ouput' (did you mean --output?)"),
    (["replya", SESSION], 2, "wiretape: error: unknown command 'replya' (did you mean replay?)"),
    (["shwo", SESSION], 2, "wiretape: error: unknown command 'shwo' (did you mean show?)"),
    (["teleport"], 2, "wiretape: error: unknown command 'teleport' (see wiretape --help)"),
    (["record", "--device", "type=serial,devcie=/dev/ttyUSB0", "--pty", "{tmp}/tty",
      "-o", "{tmp}/out.wtape"], 2,
     "wiretape record: error: unknown option 'devcie' for type=serial; did you mean 'device'?"),
    (["record", "--device", "type=tcp,host=127.0.0.1,prot=5000", "--pty", "{tmp}/tty",
      "-o", "{tmp}/out.wtape"], 2,
     "wiretape record: error: unknown option 'prot' for type=tcp; did you mean 'port'?"),
    (["record", "--device", "type=serial,,device=/dev/ttyUSB0", "--pty", "{tmp}/tty",
      "-o", "{tmp}/out.wtape"], 2,
     "wiretape record: error: option string: an empty option at position 12 (nothing "
     "between the commas at positions 11 and 12)"),
    (["record", "--device", "type=tcp,host=no-such-host.invalid,port=1", "--pty", "{tmp}/tty",
      "-o", "{tmp}/out.wtape"], 3,
     ["wiretape record: error: tcp no-such-host.invalid:1: cannot resolve host "
      "'no-such-host.invalid': "]),
]


NAMES = ["option typo", "bad choice", "missing -o", "typo leaving -o missing",
         "command typo replya", "command typo shwo",
         "unknown command", "key typo devcie", "key typo prot", "empty member", "unknown host"]


@pytest.mark.parametrize("argv, code, expected", CASES, ids=NAMES)
def test_a_mistake_is_one_line_naming_it(capsys, tmp_path, argv, code, expected):
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in argv]
    status, err = run(capsys, argv)
    assert err.endswith("\n") and err.count("\n") == 1, err
    line = err.rstrip("\n")
    if isinstance(expected, str):
        assert line == expected
    else:
        for part in expected:
            assert part in line, line
    assert status == code
    assert not (tmp_path / "out.wtape").exists()


def test_an_unknown_host_is_the_resolver_s_reason_alone(capsys, tmp_path):
    """getaddrinfo's own text ("Name or service not known"), not an errno's
    text after it that contradicts it ("No route to host")."""
    _, err = run(capsys, ["record", "--device", "type=tcp,host=no-such-host.invalid,port=1",
                          "--pty", str(tmp_path / "tty"), "-o", str(tmp_path / "out.wtape")])
    reason = err.rstrip("\n").rsplit("cannot resolve host 'no-such-host.invalid': ", 1)[1]
    assert ": " not in reason, err
    assert "No route to host" not in err
