"""The `taa-study` command: the group (study.commands.common) and its commands, registered on import."""
import sys

try:
    from study.commands import (paper_command, results_command,  # noqa: F401  (they register their commands)
                                scene_commands, study_commands)
except RuntimeError as exc:
    # backend.BackendError at import (TAA_VARIANT, libLLVM): an environment to fix, not a crash.
    # Matched by name: the failed import of `backend` took its module out of sys.modules.
    if type(exc).__name__ != "BackendError":
        raise
    print(f"error: {exc}", file=sys.stderr)
    sys.exit(2)
from study.commands.common import main

__all__ = ["main"]
