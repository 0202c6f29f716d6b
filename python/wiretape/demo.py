"""`wiretape demo` / `make demo`: record a (simulated) Hokuyo URG-04LX through
wiretape, replay the recording with the simulator gone, and show that the
driver reads the same scans both times.

The helpers here (finding the repository, starting the simulator, recording
hokuyo-scan) are also used by examples/hokuyo/recordings/make_recordings.py.
"""
import json
import os
import pathlib
import sys
import tempfile
import time

from ._core import option_string
from .children import Child
from .options import join_options

SCAN_ARGS = ["--json", "--scans", "3"]


class DemoError(RuntimeError):
    pass


#: Where a wheel installs the demo's simulator (sim/) and hokuyo-scan
#: (examples/hokuyo/CMakeLists.txt); absent in a checkout.
PACKAGED_DEMO = pathlib.Path(__file__).resolve().parent / "_demo"


def find_demo(repo_root=None):
    """(the simulator's folder, hokuyo-scan, the folder for the recording):
    those installed with the package (a wheel), else the checkout's."""
    packaged_sim = PACKAGED_DEMO / "sim"
    packaged_program = PACKAGED_DEMO / "hokuyo-scan"
    if repo_root is None and (packaged_sim / "__main__.py").exists() and \
            packaged_program.exists():
        out_dir = pathlib.Path(tempfile.gettempdir()) / f"wiretape-demo-{os.getuid()}"
        return packaged_sim, packaged_program, out_dir
    repo = find_repo(repo_root)
    return repo / "examples" / "hokuyo" / "sim", find_program(repo), repo / "build" / "demo"


def find_repo(repo_root=None):
    """The wiretape checkout: `repo_root`, else the one holding this file,
    else the current directory or one of its parents."""
    candidates = []
    if repo_root is not None:
        candidates.append(pathlib.Path(repo_root))
    here = pathlib.Path(__file__).resolve()
    candidates += list(here.parents)
    cwd = pathlib.Path.cwd().resolve()
    candidates += [cwd, *cwd.parents]
    for candidate in candidates:
        if (candidate / "examples" / "hokuyo" / "sim" / "__main__.py").exists():
            return candidate
    raise DemoError("cannot find the wiretape repository (examples/hokuyo/sim); "
                    "run from inside the checkout or pass repo_root")


def find_program(repo):
    bin_dir = pathlib.Path(os.environ.get("WIRETAPE_BIN_DIR", repo / "build" / "bin"))
    program = bin_dir / "hokuyo-scan"
    if not program.exists():
        raise DemoError(f"{program} is not built; run `make` first")
    return program


class Simulator:
    """The simulated scanner as a child process, started when its ready line
    has been printed. `where`: the checkout, or the simulator's own folder."""

    def __init__(self, where, *args, deadline_s=15.0):
        where = pathlib.Path(where)
        sim = where if (where / "__main__.py").exists() else where / "examples" / "hokuyo" / "sim"
        self.child = Child([sys.executable, str(sim), *args], separate_stderr=True, text=True,
                           grace=10.0)
        if not self.child.wait_for_output(_ready_line, deadline_s):
            if self.child.running:
                self.stop()
                raise DemoError(f"the simulator did not start within {deadline_s} s")
            raise DemoError("the simulator exited: " + self.child.run().stderr.strip())
        line = next(line for line in self.child.stdout.splitlines() if line.startswith("ready "))
        self.fields = dict(f.split("=", 1) for f in line.split()[1:])

    @property
    def port_options(self):
        if "tcp" in self.fields:
            host, port = self.fields["tcp"].rsplit(":", 1)
            return option_string([("type", "tcp"), ("host", host), ("port", port)])
        return option_string([("type", "serial"), ("device", self.fields["link"])])

    def stop(self):
        self.child.end()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def _ready_line(output):
    return any(line.startswith("ready ") for line in output.splitlines(keepends=True)
               if line.endswith("\n"))


def wiretape_command(*args):
    return [sys.executable, "-m", "wiretape.cli", *args]


def wait_for_path(path, still_running, describe, deadline_s=15.0):
    """Waits until `path` exists (the proxy's pty link) or the proxy ends."""
    end = time.monotonic() + deadline_s
    while not os.path.lexists(path):
        if not still_running():
            raise DemoError(f"{describe} ended before making {path}")
        if time.monotonic() > end:
            raise DemoError(f"{describe} made no {path} within {deadline_s} s")
        time.sleep(0.02)


# hokuyo-scan takes a few seconds; far more is a hang.
_PROGRAM_DEADLINE_S = 60.0


def _run_program(program, port, scan_args):
    """hokuyo-scan's Outcome (returncode, stdout, stderr)."""
    outcome = Child([str(program), "--port", port, *scan_args], separate_stderr=True,
                    text=True).run(_PROGRAM_DEADLINE_S)
    if outcome.timed_out:
        raise DemoError(f"{program} did not finish within {_PROGRAM_DEADLINE_S:g} s")
    return outcome


def record_scan(program, sim, output, scan_args, workdir, proxy):
    """Runs hokuyo-scan against `sim`, recording the session into `output`.
    Through the proxy (`proxy` = "cli" or "bridge"), hokuyo-scan opens the
    proxy's pty and the proxy forwards to the simulator; with `proxy` None
    the library records the port hokuyo-scan opens (`log=`)."""
    output = pathlib.Path(output)
    if output.exists():
        output.unlink()
    if not proxy:
        return (_run_program(program, join_options(sim.port_options,
                                                   option_string([("log", output)])),
                             scan_args),
                "library (log=)")
    link = pathlib.Path(workdir) / "proxy-pty"
    client_port = option_string([("type", "serial"), ("device", link)])
    if proxy == "bridge":
        from . import bridge
        handle = bridge.record(sim.port_options, output, pty=link, quiet=True)
        try:
            wait_for_path(link, lambda: handle.running, "the record proxy")
            result = _run_program(program, client_port, scan_args)
        finally:
            handle.stop()
            handle.wait(15)
        outcome = handle.result()
        if not outcome.ok:
            raise DemoError(f"the record proxy failed: {outcome.message}")
        return result, "proxy (wiretape.bridge.record)"
    # Ended by SIGTERM, wiretape record ends as on Ctrl-C: the file complete.
    recorder = Child(wiretape_command("record", "--device", sim.port_options, "--pty",
                                      str(link), "-o", str(output)), text=True, grace=15.0)
    try:
        wait_for_path(link, lambda: recorder.running, "wiretape record")
        result = _run_program(program, client_port, scan_args)
    finally:
        returncode = recorder.end()
    if returncode != 0:
        raise DemoError(f"wiretape record failed ({returncode}): " + recorder.stdout.strip())
    return result, "proxy (wiretape record)"


def replay_scan(program, recording, scan_args, *replay_keys):
    port = join_options(option_string([("type", "replay"), ("file", recording)]), *replay_keys)
    return _run_program(program, port, scan_args)


def parse_scans(result):
    return [json.loads(line) for line in result.stdout.splitlines() if line.strip()]


def _summary(scan):
    first = " ".join(str(r) for r in scan["ranges"][:4])
    return f"t={scan['timestamp_ms']:>6} ms  {len(scan['ranges'])} ranges  [{first} ...]"


def run(repo_root=None):
    started = time.monotonic()
    try:
        sim_dir, program, out_dir = find_demo(repo_root)
    except DemoError as error:
        print(f"wiretape demo: {error}", file=sys.stderr)
        return 3
    out_dir.mkdir(parents=True, exist_ok=True)
    recording = out_dir / "urg04lx-demo.wtape"

    print("wiretape demo: record a Hokuyo URG-04LX (simulated), then replay it without it")
    with tempfile.TemporaryDirectory(prefix="wiretape-demo-") as workdir:
        try:
            with Simulator(sim_dir, "--model", "urg04lx", "--pty",
                           str(pathlib.Path(workdir) / "urg04lx")) as sim:
                print(f"  1. simulator up on {sim.fields.get('pty')}")
                recorded, method = record_scan(program, sim, recording, SCAN_ARGS,
                                               workdir, "cli")
            print(f"  2. recorded hokuyo-scan {' '.join(SCAN_ARGS)} via {method}")
            print(f"     -> {recording}")
            print("  3. simulator stopped")
        except DemoError as error:
            print(f"wiretape demo: {error}", file=sys.stderr)
            return 3
    if recorded.returncode != 0:
        print(f"wiretape demo: hokuyo-scan failed while recording:\n{recorded.stderr}",
              file=sys.stderr)
        return 3
    replayed = replay_scan(program, recording, SCAN_ARGS)
    print(f"  4. replayed the recording to hokuyo-scan (type=replay,file={recording.name})")
    if replayed.returncode != 0:
        print(f"wiretape demo: hokuyo-scan failed on replay:\n{replayed.stderr}",
              file=sys.stderr)
        return 1

    live, again = parse_scans(recorded), parse_scans(replayed)
    width = 56
    print()
    print(f"  {'scan':<5}{'live simulator':<{width}}replayed recording")
    for i in range(max(len(live), len(again))):
        left = _summary(live[i]) if i < len(live) else "-"
        right = _summary(again[i]) if i < len(again) else "-"
        mark = "=" if i < len(live) and i < len(again) and live[i] == again[i] else "!"
        print(f"  {i + 1:<3}{mark} {left:<{width}}{right}")
    print()
    agree = live == again and len(live) > 0
    if agree:
        print(f"  agree: {len(live)} scans, every range and timestamp identical "
              f"({time.monotonic() - started:.1f} s)")
    else:
        print("  DISAGREE: the replayed scans differ from the live ones")

    broken = replay_scan(program, recording, SCAN_ARGS + ["--inject-bug"])
    caught = broken.returncode == 1 and "mismatch" in broken.stderr
    print(f"  and a driver with a deliberate bug is {'caught' if caught else 'NOT caught'}"
          " by the same recording:")
    for line in broken.stderr.splitlines()[-8:]:
        if line.strip():
            print("    " + line)
    robust = fault_campaign(program, recording)
    print(f"\n  try: wiretape show {recording}")
    return 0 if agree and robust else 1


# A short fault campaign (docs/faults.md): a few kinds at exchanges sampled
# from the recording (24 runs, seed 0), each against its own faulty virtual
# device; well under 15 s.
DEMO_FAULT_KINDS = ["drop", "corrupt", "truncate", "silence", "disconnect"]


def fault_campaign(program, recording):
    from . import faults

    started = time.monotonic()
    argv = [str(program), "--port", faults.PORT_PLACEHOLDER, *SCAN_ARGS, "--timeout", "0.5"]
    try:
        result = faults.campaign(str(recording), argv, kinds=DEMO_FAULT_KINDS, budget=24,
                                 seed=0, timeout=10, jobs=2, replay_options="timing=none")
    except (faults.FaultInputError, faults.CleanRunFailed) as error:
        print(f"  fault campaign: {error}")
        return False
    print(f"\n  5. a fault campaign: hokuyo-scan against {len(result.runs)} faulty replays "
          f"({time.monotonic() - started:.1f} s)")
    for line in faults.table(result).splitlines():
        print("     " + line)
    for run in result.runs:
        if run.repro:
            print(f"     {run.outcome}: {run.repro}")
    return not result.failed


if __name__ == "__main__":
    sys.exit(run())
