"""Bridges between a device and a client: the record proxy, the port server
and virtual devices (replay on a pty or TCP). Placeholder until it lands."""


def record(device, output, *, pty=None, listen=None, duration=None, meta=None):
    raise NotImplementedError("wiretape record is not built yet")


def serve(device, listen, *, output=None, protocol="raw", shared=False, reopen=False):
    raise NotImplementedError("wiretape serve is not built yet")


def serve_replay(file, *, pty=None, listen=None, replay_options="", restart=False):
    raise NotImplementedError("wiretape replay is not built yet")
