"""mocap-workbench: clean motion-capture data and compare cleaning methods."""

__version__ = "0.1.0"
