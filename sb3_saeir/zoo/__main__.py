"""``python -m sb3_saeir.zoo train|enjoy [rl-zoo3 arguments]``: :func:`sb3_saeir.zoo.launcher.main`."""

import sys

from sb3_saeir.zoo.launcher import main

if __name__ == "__main__":
    sys.exit(main())
