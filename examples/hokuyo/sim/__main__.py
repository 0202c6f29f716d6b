"""python examples/hokuyo/sim --model urg04lx|utm30lx (--pty LINK | --listen HOST:PORT)

Prints one line `ready pty=/dev/pts/N link=LINK` (or `ready tcp=HOST:PORT`)
on stdout once a client can connect; SIGTERM or Ctrl-C stops it cleanly.
"""
import argparse
import os
import signal
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scip_sim  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog=f"python {sys.argv[0]}",  # the folder, as run: in a checkout or a wheel
        description="A simulated Hokuyo laser scanner speaking SCIP 2.0.")
    parser.add_argument("--model", choices=sorted(scip_sim.MODELS), default="urg04lx")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--pty", metavar="LINK",
                       help="serve on a new pseudo-terminal, symlinked at LINK")
    where.add_argument("--listen", metavar="HOST:PORT", help="serve on TCP (port 0: any)")
    parser.add_argument("--scip2", action="store_true",
                        help="power on in SCIP 2.0 (the URG-04LX starts in SCIP 1.1)")
    parser.add_argument("--laser-on", action="store_true", help="laser on at power-on")
    parser.add_argument("--start-time-ms", type=int, default=0,
                        help="the device clock at the first command (24-bit, wraps)")
    parser.add_argument("--bad-sum", action="append", default=[], metavar="CMD",
                        help="corrupt one data-line sum in the next reply to CMD (e.g. GD); "
                             "repeat to spoil several replies")
    parser.add_argument("--garbage", action="append", default=[], metavar="CMD",
                        help="send garbage before the next reply to CMD; repeatable")
    parser.add_argument("--fault", metavar="NN",
                        help="power on with hardware fault status NN (as DBNN does)")
    parser.add_argument("--verbose", action="store_true", help="log commands on stderr")
    args = parser.parse_args(argv)

    device = scip_sim.Device(args.model, scip2=True if args.scip2 else None,
                             laser_on=args.laser_on, start_time_ms=args.start_time_ms,
                             bad_sum=args.bad_sum, garbage=args.garbage)
    device.laser = args.laser_on
    if args.fault:
        if len(args.fault) != 2:
            parser.error("--fault: a two-character status such as 55")
        device.fault = args.fault.encode()

    stopping = []
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(1))
    signal.signal(signal.SIGINT, lambda *_: stopping.append(1))

    def log(text):
        if args.verbose:
            print("sim: " + text, file=sys.stderr, flush=True)

    def ready(text):
        print("ready " + text, flush=True)

    try:
        if args.pty:
            scip_sim.serve_pty(device, args.pty, log, lambda: bool(stopping), ready)
        else:
            host, _, port = args.listen.rpartition(":")
            if not port.isdigit():
                parser.error("--listen: expected HOST:PORT, got %r" % args.listen)
            scip_sim.serve_tcp(device, host or "127.0.0.1", int(port), log,
                               lambda: bool(stopping), ready)
    except OSError as error:
        print("sim: %s" % error, file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
