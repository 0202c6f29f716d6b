"""Conversions between session formats. Placeholder."""


def convert(src, dst, from_format=None, to_format=None, progress=False):
    raise NotImplementedError
