"""The run wing: one training run in its folder (:mod:`sb3_saeir.run.run`), the folder it owns
(:mod:`sb3_saeir.run.folder`: claimed, found or taken; locked by :mod:`sb3_saeir.run.lock`), what the folder records
(:mod:`sb3_saeir.run.record`, the file names in :mod:`sb3_saeir.run.files`) and what a run shows while it trains
(:mod:`sb3_saeir.run.output`)."""

from sb3_saeir.run.folder import RunFolder
from sb3_saeir.run.lock import RunFolderInUseError
from sb3_saeir.run.output import RunOutput
from sb3_saeir.run.record import RunSpec
from sb3_saeir.run.run import Run, RunStoppedError

__all__ = ["Run", "RunFolder", "RunFolderInUseError", "RunOutput", "RunSpec", "RunStoppedError"]
