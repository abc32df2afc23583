"""``python -m mpsbench``: the same as the ``mpsbench`` command."""

import sys

from mpsbench.cli import main

sys.exit(main())
