"""Reading session files for people: show, stats, verify. Placeholder."""


def show(path, fmt="text", decode=None, out=None):
    raise NotImplementedError


def stats(path):
    raise NotImplementedError


def verify(path):
    raise NotImplementedError
