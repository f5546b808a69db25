"""``python -m sb3_saeir.zoo train|enjoy [rl-zoo3 arguments]``: :func:`sb3_saeir.zoo.launcher.main`."""

from sb3_saeir.common.stop_signals import exit_after_the_command
from sb3_saeir.zoo.launcher import main

if __name__ == "__main__":
    exit_after_the_command(main())
