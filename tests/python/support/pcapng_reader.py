"""A small pcapng reader independent of the export's writer, for the
tests of the pcapng export."""

import struct


def read_pcapng(path):
    """A small independent pcapng reader: (interfaces, packets) where each
    packet is (interface name, timestamp ns, flags, payload, comment)."""
    blob = path.read_bytes()
    offset = 0
    interfaces = []
    packets = []
    section_comment = None

    def options(body, every=None):
        """{code: first value}; `every`, a dict, gets {code: [each value]}
        (an option that repeats, as comments may)."""
        found = {}
        position = 0
        while position + 4 <= len(body):
            code, length = struct.unpack_from("<HH", body, position)
            position += 4
            if code == 0:
                break
            found.setdefault(code, body[position:position + length])
            if every is not None:
                every.setdefault(code, []).append(body[position:position + length])
            position += length + (-length % 4)
        return found

    while offset < len(blob):
        block_type, length = struct.unpack_from("<II", blob, offset)
        assert length >= 12 and length % 4 == 0, f"bad block length {length} at {offset}"
        (trailer,) = struct.unpack_from("<I", blob, offset + length - 4)
        assert trailer == length, f"block at {offset}: trailing length differs"
        body = blob[offset + 8:offset + length - 4]
        if block_type == 0x0A0D0D0A:
            magic, major, minor = struct.unpack_from("<IHH", body)
            assert (magic, major, minor) == (0x1A2B3C4D, 1, 0)
            # The section's comments, joined, are the header JSON
            # (several when it is longer than one option holds).
            every = {}
            options(body[16:], every)
            section_comment = b"".join(every.get(1, [])).decode()
        elif block_type == 1:
            link_type, _, _ = struct.unpack_from("<HHI", body)
            opts = options(body[8:])
            interfaces.append({"link_type": link_type, "name": opts[2].decode(),
                               "tsresol": opts.get(9)})
        elif block_type == 6:
            interface, high, low, captured, original = struct.unpack_from("<IIIII", body)
            payload = body[20:20 + captured]
            assert captured == original
            opts = options(body[20 + captured + (-captured % 4):])
            flags = struct.unpack("<I", opts[2])[0] if 2 in opts else 0
            comment = opts[1].decode() if 1 in opts else None
            packets.append((interfaces[interface]["name"], (high << 32) | low, flags,
                            payload, comment))
        offset += length
    return section_comment, interfaces, packets
