"""wiretape ports: the serial devices the system knows."""

from __future__ import annotations

import os
from typing import Dict, List

from .console import Output
from .errors import EXIT_OK


def _by_id_links(directory: str = "/dev/serial/by-id") -> Dict[str, List[str]]:
    """Real device path -> the stable /dev/serial/by-id links to it."""
    links: Dict[str, List[str]] = {}
    try:
        names = sorted(os.listdir(directory))
    except OSError:  # no USB serial devices, or not Linux
        return links
    for name in names:
        path = os.path.join(directory, name)
        links.setdefault(os.path.realpath(path), []).append(path)
    return links


def serial_ports() -> List[dict]:
    """The serial devices the OS knows: device, by-id paths, USB ids, text."""
    from serial.tools import list_ports

    by_id = _by_id_links()
    ports = []
    for info in sorted(list_ports.comports(), key=lambda p: p.device):
        vid_pid = None
        if info.vid is not None and info.pid is not None:
            vid_pid = f"{info.vid:04x}:{info.pid:04x}"
        description = info.description if info.description not in (None, "n/a") else ""
        ports.append({
            "device": info.device,
            "by_id": by_id.get(os.path.realpath(info.device), []),
            "vid_pid": vid_pid,
            "description": description,
            "manufacturer": info.manufacturer,
            "product": info.product,
            "serial_number": info.serial_number,
            "location": info.location,
            "hwid": info.hwid,
        })
    return ports


def cmd_ports(args, out: Output) -> int:
    ports = serial_ports()
    if args.json:
        import json  # for --json only: not on every command's start-up

        print(json.dumps(ports, indent=2))
        return EXIT_OK
    if not ports:
        out.note("no serial ports found")
        return EXIT_OK
    rows = [(p["device"], "\n".join(p["by_id"]) or "-", p["vid_pid"] or "-",
             p["description"] or "-") for p in ports]
    out.table(("device", "by-id", "usb", "description"), rows)
    return EXIT_OK
