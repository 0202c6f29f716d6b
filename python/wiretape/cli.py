"""The wiretape command line. Placeholder."""
import sys

from . import __version__


def main(argv=None):
    print(f"wiretape {__version__}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
