"""The `taa-study` command: the group (study.commands.common) and its commands, registered on import."""
from study.commands import scene_commands, study_commands  # noqa: F401  (they register their commands)
from study.commands.common import main

__all__ = ["main"]
