"""`wiretape replay FILE --as PATH -- CMD` against CMD on the device's
simulator (issue 42, replay_as_overhead_ratio): hokuyo-scan --json, once
against examples/hokuyo/sim on a pty (started before, so that its start-up
is not counted), once through the replay of a recording of that very
conversation, the whole command line timed; interleaved, the median of the
per-pair ratios. The recording is made here, before the rounds, by
`wiretape record --device LINK -- hokuyo-scan --port LINK --json` against
the same running simulator, after one run that puts it in the state every
timed run finds (SCIP 2.0, as a first run leaves it): the replay then plays the simulator's own
answers at their own pace, so the ratio is the replay's cost (a
recording made elsewhere may hold another conversation: the checked-in
urg04lx_gd.wtape answers the first two VV with an error, which costs the
driver its own quiet-line waits).

wiretape runs with a bytecode cache (PYTHONPYCACHEPREFIX in WORKDIR, filled
by the recording run and one replay), as from an installed package, which holds its
compiled modules: with PYTHONDONTWRITEBYTECODE set, as on the bench
machine, every timed run would compile the CLI's modules again
(bench/replay_ready_bench.py does the same).

The simulator answers a scan (GD) at its next scan boundary, every 100 ms,
so a conversation with it takes 0-100 ms more or less by chance, and a
replay takes what its recording took: 9 recordings are made, each after a
random wait of up to a scan period, and the one whose conversation
(client_connect to client_disconnect) took the median time is replayed,
so that the figure is not one draw of the scan's phase.

Prints one JSON line: {"ratio": median, "ratios": [...], "simulator_s":
median, "replay_s": median, "recorded_s": the replayed recording's run time,
"conversation_s": its conversation, "conversations_s": those of the 9}.

Usage: python replay_as_bench.py HOKUYO_SCAN WORKDIR ROUNDS
"""

from __future__ import annotations

import json
import os
import random
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RECORDINGS = ROOT / "examples" / "hokuyo" / "recordings"
DEADLINE_S = 60.0
# Recordings made, of which the median conversation is replayed, each after
# a wait of up to a scan period (the urg04lx's 600 rpm), so that each finds
# the simulator's scan at a phase of its own.
RECORDINGS_MADE = 9
SCAN_PERIOD_S = 0.1
# wiretape's environment: its compiled modules cached (see above).
CHILD_ENV = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}


def timed(command: list[str]) -> float:
    start = time.perf_counter()
    proc = subprocess.run(command, capture_output=True, text=True, timeout=DEADLINE_S,
                          env=CHILD_ENV)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed: "
                         + (proc.stderr.strip().splitlines() or ["?"])[-1])
    return seconds


def conversation_s(recording: Path) -> float:
    """Seconds from the recording's client_connect to its client_disconnect."""
    import wiretape

    with wiretape.SessionReader(str(recording)) as reader:
        times = {record.kind: record.t_ns for record in reader
                 if record.kind in ("client_connect", "client_disconnect")}
    return (times["client_disconnect"] - times["client_connect"]) / 1e9


def main() -> int:
    program, work, rounds = sys.argv[1], Path(sys.argv[2]), int(sys.argv[3])
    work.mkdir(parents=True, exist_ok=True)
    CHILD_ENV["PYTHONPYCACHEPREFIX"] = str(work / "pycache")
    meta = json.loads((RECORDINGS / "urg04lx_gd.json").read_text())
    link = work / f"sim-{os.getpid()}.pty"
    simulator = subprocess.Popen([sys.executable, str(ROOT / "examples" / "hokuyo" / "sim"),
                                  *meta["simulator"], "--pty", str(link)],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        start = time.perf_counter()
        while not link.exists():
            if simulator.poll() is not None:
                raise SystemExit("the simulator ended: " + simulator.stderr.read().decode())
            if time.perf_counter() - start > DEADLINE_S:
                raise SystemExit(f"the simulator made no {link} in {DEADLINE_S:.0f} s")
            time.sleep(0.01)  # waiting for another process's link
        script = Path(sys.executable).parent / "wiretape"
        wiretape = [str(script)] if script.exists() else [sys.executable, "-m", "wiretape.cli"]
        against_simulator = [program, "--port", str(link), *meta["args"]]
        # The simulator keeps its mode from one client to the next, as the
        # device does: the first run switches it to SCIP 2.0 (its VV and QT
        # are answered with an error until then), every later one finds it
        # there. One run first, so that the recording holds the conversation
        # the timed runs have.
        timed(against_simulator)
        # The simulator answers GD at its next scan (every 100 ms), so each
        # conversation waits 0-100 ms for it, and a replay waits what its
        # recording waited: of several recordings, the one whose
        # conversation took the median time is replayed.
        recordings = []
        chance = random.Random(42)
        for number in range(RECORDINGS_MADE):
            # Runs back to back would find the scan at much the same phase.
            time.sleep(chance.uniform(0, SCAN_PERIOD_S))
            recording = work / f"conversation-{os.getpid()}-{number}.wtape"
            recorded_s = timed([*wiretape, "record", "--device", str(link), "-o",
                                str(recording), "-q", "--", program, "--port", str(link),
                                *meta["args"]])
            recordings.append((conversation_s(recording), recorded_s, recording))
        recordings.sort()
        conversation, recorded_s, recording = recordings[len(recordings) // 2]
        through_replay = [*wiretape, "replay", str(recording), "-q",
                          "--as", "/dev/ttyBENCH0", "--", program, "--port", "/dev/ttyBENCH0",
                          *meta["args"]]
        timed(through_replay)  # the modules record did not import cached too
        times: dict[str, list[float]] = {"simulator": [], "replay": []}
        for index in range(rounds):
            order = ("simulator", "replay") if index % 2 == 0 else ("replay", "simulator")
            for kind in order:
                times[kind].append(timed(against_simulator if kind == "simulator"
                                         else through_replay))
    finally:
        simulator.send_signal(signal.SIGINT)
        try:
            simulator.wait(10)
        except subprocess.TimeoutExpired:
            simulator.kill()
    ratios = [r / s for r, s in zip(times["replay"], times["simulator"])]
    print(json.dumps({"ratio": statistics.median(ratios), "ratios": ratios,
                      "simulator_s": statistics.median(times["simulator"]),
                      "replay_s": statistics.median(times["replay"]),
                      "recorded_s": recorded_s, "conversation_s": conversation,
                      "conversations_s": [made[0] for made in recordings]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
