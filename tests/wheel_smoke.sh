#!/usr/bin/env bash
# The wheel, installed into a fresh venv away from the checkout, tried there:
# `wiretape demo` (the simulator and hokuyo-scan ship inside it), the pytest
# plugin replaying a cassette, pyserial's wiretape:// URL, the preload shim.
# Usage: tests/wheel_smoke.sh [DIST_DIR [PYTHON]]   (make wheel-smoke)
# PYTHON (default python3) makes the venv; pip picks the wheel of DIST_DIR
# that fits it (cpXY, or cp312-abi3 for 3.12 and later).
set -euo pipefail

dist=$(cd "${1:-dist}" && pwd)
python=${2:-python3}
shopt -s nullglob
wheels=("$dist"/wiretape-*.whl)
if [ ${#wheels[@]} -eq 0 ]; then
  echo "wheel_smoke: no wiretape wheel in $dist (make wheel)" >&2
  exit 1
fi
work=$(mktemp -d -t wiretape-wheel-smoke.XXXXXX)
trap 'rm -rf "$work"' EXIT
cd "$work"  # nothing may come from the checkout

"$python" -m venv venv
# The wheel from DIST_DIR alone; its dependencies and pytest from the index.
venv/bin/python -m pip install -q --no-index --find-links "$dist" --no-deps wiretape || {
  echo "wheel_smoke: no wheel in $dist fits $("$python" --version) (make wheel)" >&2; exit 1; }
venv/bin/python -m pip install -q wiretape "pytest>=7" --find-links "$dist"
installed=$(venv/bin/python -c "import importlib.metadata as m; print(m.version('wiretape'))")
PATH="$work/venv/bin:$PATH"
step() { echo "wheel_smoke: $*"; }

step "wiretape demo"
wiretape demo > demo.out 2>&1 || { cat demo.out; exit 1; }
grep -q "agree:" demo.out || { cat demo.out; echo "wheel_smoke: the demo did not agree" >&2; exit 1; }

step "wiretape convert (a session from JSON lines)"
cat > ping.jsonl <<'JSONL'
{"header": {"port_type": "serial", "capture": "client"}}
{"t_ns": 1000, "kind": "tx", "data_hex": "50494e470a"}
{"t_ns": 2000, "kind": "rx", "data_hex": "504f4e470a"}
JSONL
wiretape convert ping.jsonl ping.wtape -q

step "pyserial serial_for_url('wiretape://...')"
python - <<'PY'
import serial
import wiretape  # registers the wiretape:// URL scheme

port = serial.serial_for_url("wiretape://ping.wtape?unused=error", timeout=10)
port.write(b"PING\n")
answer = port.readline()
port.close()
assert answer == b"PONG\n", answer
PY

step "the pytest plugin (entry point pytest11)"
cat > test_ping.py <<'PY'
import pytest
import serial


@pytest.mark.wiretape(cassette="ping.wtape")
def test_ping(wiretape_url):
    port = serial.serial_for_url(wiretape_url, timeout=10)
    port.write(b"PING\n")
    assert port.read_until(b"\n") == b"PONG\n"
    port.close()
PY
python -m pytest -q -p no:cacheprovider test_ping.py

step "the preload shim (replay --as /dev/ttyUSB7 -- CMD)"
cat > ping_client.py <<'PY'
import serial

port = serial.Serial("/dev/ttyUSB7", 9600, timeout=10)
port.write(b"PING\n")
assert port.read_until(b"\n") == b"PONG\n"
port.close()
PY
wiretape replay ping.wtape --as /dev/ttyUSB7 -- python ping_client.py
step "ok: wiretape $installed on $(venv/bin/python --version)"
