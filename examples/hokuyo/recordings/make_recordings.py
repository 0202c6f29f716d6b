"""Re-creates the recordings in this folder: hokuyo-scan against the
simulator, recorded by `wiretape record` (the transparent proxy) when it is
available, else by the library (`log=`). Each NAME.wtape gets a NAME.json with
the hokuyo-scan arguments and the scans it printed, which the tests expect
from a replay.

    .venv/bin/python examples/hokuyo/recordings/make_recordings.py [--library]
"""
import argparse
import json
import pathlib
import sys
import tempfile

HERE = pathlib.Path(__file__).resolve().parent

from wiretape import demo  # noqa: E402

# name: (simulator arguments, hokuyo-scan arguments)
RECORDINGS = {
    # SCIP 1.1 at power-on: VV fails, SCIP2.0, VV again; then one GD scan.
    "urg04lx_gd": (["--model", "urg04lx"], ["--json"]),
    # A counted MD stream with clustering.
    "urg04lx_md": (["--model", "urg04lx", "--scip2"],
                   ["--json", "--mode", "md", "--scans", "3", "--cluster", "3"]),
    # The UTM-30LX ME stream (ranges and intensities) on part of its range.
    "utm30lx_me": (["--model", "utm30lx"],
                   ["--json", "--mode", "me", "--scans", "2", "--first", "100",
                    "--last", "600"]),
    # GS across the device clock's 24-bit wrap.
    "urg04lx_gs_wrap": (["--model", "urg04lx", "--scip2", "--start-time-ms", "16777100"],
                        ["--json", "--mode", "gs", "--scans", "3", "--first", "300",
                         "--last", "400"]),
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--library", action="store_true",
                        help="record with the library (log=) instead of the `wiretape record` proxy")
    parser.add_argument("names", nargs="*", default=sorted(RECORDINGS))
    args = parser.parse_args(argv)
    repo = demo.find_repo()
    program = demo.find_program(repo)
    proxy = None if args.library else "cli"
    for name in args.names:
        sim_args, scan_args = RECORDINGS[name]
        output = HERE / f"{name}.wtape"
        with tempfile.TemporaryDirectory(prefix="hokuyo-rec-") as workdir:
            with demo.Simulator(repo, *sim_args, "--pty", f"{workdir}/sim") as sim:
                result, method = demo.record_scan(program, sim, output, scan_args,
                                                  workdir, proxy)
        if result.returncode != 0:
            print(f"{name}: hokuyo-scan failed:\n{result.stderr}", file=sys.stderr)
            return 1
        scans = demo.parse_scans(result)
        meta = {"simulator": sim_args, "args": scan_args, "recorded_with": method,
                "scans": scans}
        output.with_suffix(".json").write_text(json.dumps(meta, indent=1) + "\n")
        print(f"{name}: {len(scans)} scans via {method} -> {output.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
