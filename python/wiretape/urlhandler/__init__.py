"""pyserial URL handlers wiretape:// and wiretape+record://. Placeholder."""


def register():
    pass
