"""Makes the captures of this folder (README.md says what each holds).

Run as root (dumpcap on the loopback interface), from anywhere:
    python3 tests/data/pcap/make_captures.py
It captures real exchanges on 127.0.0.1 with dumpcap, keeps each
conversation in its own file with tshark, and damages one copy on purpose
(a segment sent twice, two segments swapped, a segment overlapping its
neighbours) by rewriting the pcap's records.
"""

import os
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
TCP_PORT, OTHER_TCP_PORT, UDP_PORT = 15021, 15022, 15023


def capture(path):
    log = open(path + ".log", "w+")
    process = subprocess.Popen(
        ["dumpcap", "-i", "lo", "-P", "-w", path, "-f",
         f"port {TCP_PORT} or port {OTHER_TCP_PORT} or port {UDP_PORT}"],
        stdout=log, stderr=log)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        log.seek(0)
        if "Capturing on" in log.read() and os.path.exists(path):
            return process
        time.sleep(0.05)
    raise SystemExit("dumpcap did not start")


def packets_in(path, display_filter):
    result = subprocess.run(["tshark", "-r", path, "-Y", display_filter], capture_output=True,
                            text=True)
    return len(result.stdout.splitlines())


def tcp_exchange(port, messages):
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", port))
    server.listen()

    def serve():
        conn, _ = server.accept()
        pending = b""
        while True:
            data = conn.recv(100)
            if not data:
                break
            pending += data
            if pending.endswith(b";"):
                conn.sendall(b"R:" + pending)
                pending = b""
        conn.close()

    thread = threading.Thread(target=serve)
    thread.start()
    client = socket.create_connection(("127.0.0.1", port))
    client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    for parts in messages:
        for part in parts:  # each part its own segment
            client.sendall(part)
            time.sleep(0.01)
        client.recv(100)
    client.close()
    thread.join()
    server.close()


def udp_exchange():
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", UDP_PORT))
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    for message in (b"PING 1", b"PING 2\x00\xff"):
        client.sendto(message, ("127.0.0.1", UDP_PORT))
        data, peer = server.recvfrom(100)
        server.sendto(b"PONG" + data[4:], peer)
        client.recvfrom(100)
    client.close()
    server.close()


def read_pcap(path):
    blob = open(path, "rb").read()
    header, records, offset = blob[:24], [], 24
    while offset < len(blob):
        seconds, micros, captured, original = struct.unpack_from("<IIII", blob, offset)
        records.append([seconds, micros, blob[offset + 16:offset + 16 + captured]])
        offset += 16 + captured
    return header, records


def write_pcap(path, header, records):
    with open(path, "wb") as out:
        out.write(header)
        for seconds, micros, frame in records:
            out.write(struct.pack("<IIII", seconds, micros, len(frame), len(frame)) + frame)


def tcp_payload(frame):
    """(offset of the TCP header, payload) of an Ethernet + IPv4 frame."""
    ip = 14
    ip_header = (frame[ip] & 0x0F) * 4
    tcp = ip + ip_header
    tcp_header = (frame[tcp + 12] >> 4) * 4
    return tcp, frame[tcp + tcp_header:]


def with_payload(frame, sequence, payload):
    """The frame carrying `payload` at `sequence` instead (checksums are not
    checked by tshark, lengths are rewritten)."""
    tcp, _ = tcp_payload(frame)
    tcp_header = (frame[tcp + 12] >> 4) * 4
    head = bytearray(frame[:tcp + tcp_header])
    struct.pack_into(">H", head, 14 + 2, len(head) - 14 + len(payload))
    struct.pack_into(">I", head, tcp + 4, sequence)
    return bytes(head) + payload


def damage(source, target):
    header, records = read_pcap(source)
    data = [i for i, (_, _, frame) in enumerate(records) if tcp_payload(frame)[1]]
    # The client's "AB", "CD;" are data packets 0 and 1; the server's reply 2;
    # the client's "hel", "lo;" 3 and 4.
    ab, cd, hel, lo = data[0], data[1], data[3], data[4]
    tcp, _ = tcp_payload(records[hel][2])
    (hel_sequence,) = struct.unpack_from(">I", records[hel][2], tcp + 4)
    # overlapping: "el" again and "lo" again, across the two segments
    overlap = with_payload(records[lo][2], hel_sequence + 1, b"ello")
    damaged = list(records)
    # out of order: the frames change places, the times stay in order
    damaged[ab] = records[ab][:2] + [records[cd][2]]
    damaged[cd] = records[cd][:2] + [records[ab][2]]
    damaged.insert(cd + 1, list(damaged[cd][:2]) + [records[cd][2]])  # "CD;" retransmitted
    damaged.insert(lo + 2, records[lo][:2] + [overlap])
    write_pcap(target, header, damaged)


def main():
    with tempfile.TemporaryDirectory() as scratch:
        everything = os.path.join(scratch, "all.pcap")
        dumpcap = capture(everything)
        tcp_exchange(TCP_PORT, [(b"AB", b"CD;"), (b"hel", b"lo;")])
        tcp_exchange(OTHER_TCP_PORT, [(b"second;",)])
        udp_exchange()
        deadline = time.monotonic() + 30
        while packets_in(everything, "tcp.flags.fin == 1") < 4 or \
                packets_in(everything, "udp") < 4:
            if time.monotonic() > deadline:
                sys.exit("the capture did not see every packet")
            time.sleep(0.1)
        dumpcap.terminate()
        dumpcap.wait()

        def keep(name, display_filter):
            subprocess.run(["tshark", "-r", everything, "-Y", display_filter, "-F", "pcap",
                            "-w", os.path.join(HERE, name)], check=True, capture_output=True)

        keep("tcp.pcap", f"tcp.port == {TCP_PORT}")
        keep("udp.pcap", f"udp.port == {UDP_PORT}")
        keep("multi.pcap", "tcp or udp")
    damage(os.path.join(HERE, "tcp.pcap"), os.path.join(HERE, "tcp-damaged.pcap"))
    blob = open(os.path.join(HERE, "tcp.pcap"), "rb").read()
    _, records = read_pcap(os.path.join(HERE, "tcp.pcap"))
    cut = 24 + sum(16 + len(frame) for _, _, frame in records[:5]) + 20
    open(os.path.join(HERE, "truncated.pcap"), "wb").write(blob[:cut])


if __name__ == "__main__":
    main()
