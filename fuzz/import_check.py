"""The contract every importer keeps on any input (issue 23): it converts,
or fails with a SessionError (exit 1) whose message names the file, with no
traceback and no internal message; on success every rx/tx record holds
bytes that are in the input (never invented), and a failure leaves no
output. Shared by the fuzz targets (fuzz/*_import_fuzz.py) and the damage
sweep (tests/python/tools/test_import_damage_sweep.py)."""

from __future__ import annotations

import base64
import binascii
import json
import os
import time

import wiretape
from wiretape.cli import EXIT_CHECK_FAILED, exit_code_for
from wiretape.tools import convert as convert_module
from wiretape.tools import importers

SUFFIX = {"pcap": ".pcap", "umockdev": ".script", "reserial": ".jsonl", "jsonl": ".jsonl"}
_INTERNAL = ("Traceback", "Invoked with", "[Errno", "nanobind")
SLOW_S = 60.0


def _lines(data: bytes):
    """The lines as the importers see them: UTF-8 text, whitespace stripped."""
    for line in data.split(b"\n"):
        yield line.decode("utf-8", "replace").strip()


def _reserial_values(data: bytes):
    for line in _lines(data):
        try:
            item = json.loads(line)
        except (ValueError, RecursionError):
            continue
        for entry in (item.values() if isinstance(item, dict) else ()):
            if not isinstance(entry, dict):
                continue
            for direction in ("rx", "tx"):
                text = entry.get(direction)
                if not isinstance(text, str):
                    continue
                try:
                    yield text.encode("utf-8")
                except UnicodeEncodeError:
                    pass
                try:
                    yield base64.b64decode(text.encode("ascii"), validate=True)
                except (UnicodeEncodeError, binascii.Error):
                    pass


def _umockdev_values(data: bytes):
    for line in data.split(b"\n"):
        _, _, rest = line[2:].partition(b" ")
        try:
            yield importers._umockdev_data(rest)
        except ValueError:
            pass


def _jsonl_values(data: bytes):
    for line in _lines(data):
        try:
            item = json.loads(line)
            yield bytes.fromhex(item["data_hex"])
        except Exception:  # noqa: BLE001 - any line that gives no bytes
            pass


def _in_input(fmt: str, data: bytes, payload: bytes) -> bool:
    if fmt == "pcap":
        return payload in data  # one packet's bytes, as captured
    values = {"reserial": _reserial_values, "umockdev": _umockdev_values,
              "jsonl": _jsonl_values}[fmt](data)
    return any(payload == value for value in values)


def check_input(fmt: str, data: bytes, scratch: str, **options) -> str:
    """Imports `data` as `fmt`; "ok" or "refused", or AssertionError when
    the contract is broken."""
    src = os.path.join(scratch, "in" + SUFFIX[fmt])
    dst = os.path.join(scratch, "out.wtape")
    with open(src, "wb") as handle:
        handle.write(data)
    if os.path.exists(dst):
        os.unlink(dst)
    started = time.monotonic()
    try:
        convert_module.convert(src, dst, from_format=fmt, to_format="wiretape", **options)
    except wiretape.SessionError as error:
        message = str(error)
        if src not in message:
            raise AssertionError(f"the message does not name the file: {message!r}") from error
        if any(text in message for text in _INTERNAL) or "\x1b" in message:
            raise AssertionError(f"an internal message or a raw escape: {message!r}") from error
        if exit_code_for(error) != EXIT_CHECK_FAILED:
            raise AssertionError(f"exit {exit_code_for(error)} for {message!r}") from error
        if fmt != "jsonl" and os.path.exists(dst):  # jsonl keeps what came before damage
            raise AssertionError(f"an output left behind after {message!r}")
        return "refused"
    finally:
        if time.monotonic() - started > SLOW_S:
            raise AssertionError(f"took {time.monotonic() - started:.0f} s (a hang?)")
    with wiretape.SessionReader(dst) as reader:
        for record in reader:
            if record.kind in ("rx", "tx") and not _in_input(fmt, data, bytes(record.data)):
                raise AssertionError(f"{record.kind} bytes not in the input: "
                                     f"{bytes(record.data)[:60]!r}")
        if reader.damage is not None:
            raise AssertionError(f"wrote a damaged session: {reader.damage}")
    return "ok"
