"""The scene runner under its former name: ``runner.run``, ``runner.plan``, the builders and
``CURVE_COLUMNS``, re-exported for the scripts and tests that import them from here."""
from .runner import CURVE_COLUMNS, build_grid, build_heights, build_tip, plan, run

__all__ = ["run", "plan", "build_grid", "build_heights", "build_tip", "CURVE_COLUMNS"]
