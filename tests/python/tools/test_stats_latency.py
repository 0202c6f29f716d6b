"""wiretape stats: latency from request to first response byte (issue 26),
percentiles overall and, with --profile, per request frame name."""

import json
import os
import threading
from pathlib import Path

import pytest

import wiretape
from wiretape import cli
from wiretape.tools.stats import stats


@pytest.fixture()
def lines_session(tmp_path: Path) -> Path:
    """Ten line exchanges: A answered after 1..9 ms, B after 100 ms; a request
    in two records waits from its last; a last request gets no answer."""
    path = tmp_path / "lines.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options="type=serial,device=/dev/ttyX") as writer:
        t = 0
        for n in range(1, 10):
            writer.write("tx", t, b"A")
            writer.write("tx", t + 500_000, b"\n")
            writer.write("rx", t + 500_000 + n * 1_000_000, b"ok\n")
            writer.write("rx", t + 500_000 + n * 1_000_000 + 100, b"more\n")
            t += 50_000_000
        writer.write("tx", t, b"B\n")
        writer.write("rx", t + 100_000_000, b"late\n")
        writer.write("tx", t + 200_000_000, b"C\n")
    return path


def test_latency_overall_is_from_the_request_to_the_first_response_byte(lines_session):
    result = stats(lines_session)
    assert [latency.name for latency in result.latency] == ["all"]
    overall = result.latency[0]
    assert overall.requests == 10
    assert overall.p50_s == pytest.approx(0.005)  # nearest rank: 5th of 10
    assert overall.p90_s == pytest.approx(0.009)
    assert overall.p99_s == pytest.approx(0.100)
    assert overall.max_s == pytest.approx(0.100)


def test_latency_per_frame_name_with_a_profile(lines_session):
    result = stats(lines_session, profile="lines")
    by_name = {latency.name: latency for latency in result.latency}
    assert set(by_name) == {"all", "A", "B"}
    assert by_name["A"].requests == 9 and by_name["A"].max_s == pytest.approx(0.009)
    assert by_name["B"].requests == 1 and by_name["B"].p50_s == pytest.approx(0.1)


def test_stats_command_prints_latency_rows_and_json(lines_session, capsys):
    assert cli.main(["stats", str(lines_session), "--profile", "lines"]) == 0
    out = capsys.readouterr().out
    assert "latency           10 requests: p50 5.000 ms, p90 9.000 ms, p99 100.000 ms, " \
           "max 100.000 ms" in out
    assert "latency B         1 request: p50 100.000 ms" in out
    assert cli.main(["stats", str(lines_session), "--json"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert document["latency"] == [{"name": "all", "requests": 10, "p50_s": 0.005,
                                    "p90_s": 0.009, "p99_s": 0.1, "max_s": 0.1}]


def test_a_pipe_gets_its_latency_too(lines_session, tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)

    def feed():
        with open(fifo, "wb") as writer:
            writer.write(lines_session.read_bytes())

    feeder = threading.Thread(target=feed)
    feeder.start()
    result = stats(str(fifo), profile="lines")
    feeder.join(timeout=30)
    assert result.records == 39
    assert [(latency.name, latency.requests) for latency in result.latency] == \
        [("all", 10), ("A", 9), ("B", 1)]


def test_a_session_without_answers_says_so(tmp_path):
    path = tmp_path / "deaf.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options="type=serial,device=/dev/ttyX") as writer:
        writer.write("rx", 0, b"hello\n")
        writer.write("tx", 1_000, b"Q\n")
        writer.write("close", 2_000, b"{}")
    result = stats(path)
    assert result.latency == ()
    assert result.latency_note == "not measured: no request is followed by a response"


def test_a_request_answered_across_a_close_and_an_open_is_paired_as_the_replay_pairs_it(
        tmp_path):
    # The one segmentation (src/replay/exchanges.cpp) keeps an exchange
    # across close/open/device_lost: the replay answers the request after
    # them, so stats pairs them too (docs/cli.md).
    path = tmp_path / "reopened.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options="type=serial,device=/dev/ttyX") as writer:
        writer.write("tx", 0, b"Q\n")
        writer.write("close", 1_000_000, b"{}")
        writer.write("open", 2_000_000, b"{}")
        writer.write("rx", 5_000_000, b"R\n")
    result = stats(path)
    assert [(latency.name, latency.requests) for latency in result.latency] == [("all", 1)]
    assert result.latency[0].max_s == pytest.approx(0.005)
    assert result.latency_note is None
    exchange, = wiretape._core.session_exchanges(str(path))
    assert (exchange.request_end_t_ns, exchange.response_start_t_ns) == (0, 5_000_000)
