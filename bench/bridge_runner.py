"""Runs the engine behind `wiretape record` / `wiretape serve` through the
Python API (wiretape.bridge) until SIGINT, with the CLI's arguments. run.py
uses it only when the installed CLI lacks the subcommand.

Usage: python bridge_runner.py record --device D (--pty P | --listen H:P | --udp H:P) -o FILE
       python bridge_runner.py serve --device D --listen H:P
"""

import argparse
import signal
import sys

import wiretape.bridge


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("command", choices=["record", "serve"])
    parser.add_argument("--device", required=True)
    parser.add_argument("--pty")
    parser.add_argument("--listen")
    parser.add_argument("--udp")
    parser.add_argument("-o", "--output")
    args = parser.parse_args()
    stopping = []
    signal.signal(signal.SIGINT, lambda *_: stopping.append(True))
    if args.command == "record":
        handle = wiretape.bridge.record(args.device, args.output, pty=args.pty,
                                        listen=args.listen, udp=args.udp, quiet=True)
    else:
        handle = wiretape.bridge.serve(args.device, args.listen, quiet=True)
    while not stopping and not handle.wait(0.1):
        pass
    handle.stop()
    handle.wait(10)
    return 0


if __name__ == "__main__":
    sys.exit(main())
