"""``python -m bpmcal.cli``: the ``bpmcal`` command (tests and benchmarks run it so)."""
import sys

from . import main

sys.exit(main())
