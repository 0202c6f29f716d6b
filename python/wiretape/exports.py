"""Exports to Wireshark (pcapng) and Foxglove (mcap). Placeholder."""


def write_pcapng(src, dst):
    raise NotImplementedError


def write_mcap(src, dst):
    raise NotImplementedError
