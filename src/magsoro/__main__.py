"""python -m magsoro: the magsoro command line."""

import sys

from magsoro.cli import main

sys.exit(main())
