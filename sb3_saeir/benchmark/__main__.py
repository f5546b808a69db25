"""``python -m sb3_saeir.benchmark``: see :mod:`sb3_saeir.benchmark`."""

import os
import sys

if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from sb3_saeir.benchmark.cli import main

    sys.exit(main())
