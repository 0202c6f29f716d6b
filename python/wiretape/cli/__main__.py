"""``python -m wiretape.cli``: the wiretape command."""

import sys

from .main import main

sys.exit(main())
