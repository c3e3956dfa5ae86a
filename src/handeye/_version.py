"""The version of handeye: the one place it is written (pyproject.toml reads it from here when the
package is built), so that reading it costs nothing (``importlib.metadata`` scans the installed
distributions: ~7 ms of every command, and the detection cache's key needs it)."""

__version__ = "0.1.0"
