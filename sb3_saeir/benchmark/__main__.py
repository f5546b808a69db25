"""``python -m sb3_saeir.benchmark``: see :mod:`sb3_saeir.benchmark`."""

import os

if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from sb3_saeir.benchmark.cli import main
    from sb3_saeir.common.stop_signals import exit_after_the_command

    exit_after_the_command(main())
