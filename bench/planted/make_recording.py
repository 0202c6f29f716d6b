"""Re-creates bench/planted/urg04lx_md15.wtape, the planted driver's
recording: hokuyo-scan (the example driver, without the planted bugs)
against the URG-04LX simulator, an MD stream of 15 scans in clusters of 3,
recorded by `wiretape record`: VV, PP, II, BM, MD and 15 scans, 20 device
answers.

    .venv/bin/python bench/planted/make_recording.py
"""
import pathlib
import sys
import tempfile

from wiretape import demo

HERE = pathlib.Path(__file__).resolve().parent
SCAN_ARGS = ["--json", "--mode", "md", "--scans", "15", "--cluster", "3"]


def main() -> int:
    repo = demo.find_repo()
    program = demo.find_program(repo)
    output = HERE / "urg04lx_md15.wtape"
    with tempfile.TemporaryDirectory(prefix="planted-rec-") as workdir:
        with demo.Simulator(repo, "--model", "urg04lx", "--scip2", "--pty", f"{workdir}/sim") as sim:
            result, method = demo.record_scan(program, sim, output, SCAN_ARGS, workdir, "cli")
    if result.returncode != 0:
        print(f"hokuyo-scan failed:\n{result.stderr}", file=sys.stderr)
        return 1
    print(f"{len(demo.parse_scans(result))} scans via {method} -> {output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
