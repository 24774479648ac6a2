"""`python -m aerobench.cli`: the same as the `aerobench` command."""

import sys

from . import main

sys.exit(main())
