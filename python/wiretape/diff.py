"""Comparing two sessions. Placeholder."""


def diff(a, b):
    raise NotImplementedError
