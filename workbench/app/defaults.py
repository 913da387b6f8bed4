"""What the app (``workbench``, ``workbench gui``, ``workbench report``) opens when told
nothing else: a take of its own module, so that the command line's parser reads these
without importing the app (matplotlib and the rest: 0.2 s and 25 MB of every command)."""

DEFAULT_CLIP = "cmu/walk/35_31"
DEFAULT_CORRUPTION = "angular:0.5+gaps:0.01"
DEFAULT_ENGINES = ("ebd>ebf", "cae", "mssa", "lerp>gaussian", "kalman")
